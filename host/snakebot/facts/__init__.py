"""What is true of the hardware, as data: the device descriptions (``devices``), the
controller's control table (``controller``) and the boards' facts from their ``board.h``
(``boards``). No I/O, no arithmetic beyond lookups.

May import: the package root (``errors``, ``core``, ``paths``) only."""
