"""Serving an emulated bus to a client in another process: a pseudo-terminal
(``PtyServer``: any program that opens a serial device) or a Unix socket
(``UnixSocketServer``: QEMU's character devices). Both run the bus on a thread with its
clock tied to the wall clock, so replies come when a real servo's would.

May import: as the ``sim`` layer (``sim.bus``, ``sim.errors``, the layers below).
"""

from snakebot.sim.transports.pty import PtyServer
from snakebot.sim.transports.unixsock import UnixSocketServer

__all__ = ["PtyServer", "UnixSocketServer"]
