"""The emulated Dynamixel bus: its virtual clock (``clock``), the wire and its timing
(``uart``, ``receiver``), seeded faults (``faults``) and the bus that ties servos to a
master port (``bus``).

May import: as the ``sim`` layer (``sim.servo``, ``sim.errors``, the layers below).
"""
