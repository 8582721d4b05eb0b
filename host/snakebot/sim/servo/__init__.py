"""The emulated AX-12: its register file (``registers``), motor (``motor``), the
reference model in Python (``reference``) and the same model with its hot path in C
(``fast``: ``VirtualServo``, what the emulator uses).

May import: as the ``sim`` layer, but no other ``sim`` package than ``sim.errors``
(the bus imports the servos, not the other way round).
"""
