"""The emulated AX-12: its register file (``registers``), motor (``motor``), the
reference model in Python (``reference``, made of its body between packets ``motion``
and its handling of Protocol 1.0 ``packets``) and the same model with its hot path in C
(``fast``: ``VirtualServo``, what the emulator uses).

May import: as the ``sim`` layer, but no other ``sim`` package than ``sim.errors``
(the bus imports the servos, not the other way round).
"""
