"""snakesim: an emulated Dynamixel bus of virtual AX-12 servos, and the world they drive.

Importing the package registers the ``sim://`` pyserial URL handler, so afterwards
``serial.serial_for_url("sim://?robot=snake5")`` (and every snakebot ``--port``) opens
an emulated bus. The pieces: ``servo`` (a virtual AX-12), ``bus`` (the wire and its
virtual clock), ``faults`` (seeded fault injection), ``options`` (what a URL or the
command line asks for), ``transports`` (pseudo-terminal and Unix-socket servers).
"""

from __future__ import annotations

import serial

HANDLER_PACKAGE = "snakesim.urlhandler"


def register_url_handler() -> None:
    """Make ``sim://`` URLs known to pyserial (idempotent)."""
    if HANDLER_PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(HANDLER_PACKAGE)


register_url_handler()
