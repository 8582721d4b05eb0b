"""The emulated Dynamixel bus: its virtual clock (``clock``), the wire and its timing
(``uart``, ``receiver``), seeded faults (``faults``) and the bus that ties servos to a
master port (``bus``: :class:`~snakebot.sim.bus.bus.Bus`, made of its event scheduler
``schedule``, its listeners ``listeners``, the line ``wire``, the servos' side
``delivery`` and the master's port ``master``, sharing the attributes of ``state``).

May import: as the ``sim`` layer (``sim.servo``, ``sim.errors``, the layers below).
"""
