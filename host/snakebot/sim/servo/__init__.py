"""The emulated AX-12: its register file (``registers``), motor (``motor``), the
reference model in Python (``reference``) and the same model with its hot path in C
(``fast``: ``VirtualServo``, what the emulator uses)."""
