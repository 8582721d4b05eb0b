"""An emulated bus behind a pseudo-terminal: a serial device any program can open.

    with PtyServer(bus) as server:
        print(server.device)   # e.g. /dev/pts/7: give it to any Dynamixel client

The server keeps the slave side open itself, so clients may open and close the device
as often as they like. The master's baud rate is the one the client set on the
terminal (read back from the pty on every write), so a client at the wrong rate is
heard as garbage by the servos, as on a real bus.
"""

from __future__ import annotations

import array
import fcntl
import os
import sys
import termios

from snakebot.sim.bus.bus import Bus
from snakebot.sim.transports.base import RawPty, ThreadedServer
from snakebot.sim.transports.pump import Pump, ServerThread

_TCGETS2 = 0x802C542A  # Linux: struct termios2 with the exact speeds
_TERMIOS2_OSPEED = 10  # index of c_ospeed in termios2 read as 32-bit ints


def tty_baudrate(fd: int) -> int | None:
    """The output speed set on the terminal ``fd`` (None if it cannot be read)."""
    if sys.platform.startswith("linux"):
        buf = array.array("i", [0] * 16)
        try:
            fcntl.ioctl(fd, _TCGETS2, buf)
            return buf[_TERMIOS2_OSPEED] or None
        except OSError:
            pass
    try:
        speed = termios.tcgetattr(fd)[5]
    except termios.error:
        return None
    for name in dir(termios):
        if name.startswith("B") and name[1:].isdigit() and getattr(termios, name) == speed:
            return int(name[1:])
    return None


class PtyServer(ThreadedServer):
    """Serves ``bus`` on a new pseudo-terminal from a background thread.

    ``link``: also make a symlink at this path to the device (removed on close).
    ``follow_baud``: take the master's baud rate from the terminal settings (default);
    otherwise the bus keeps its own ``baudrate``.
    """

    def __init__(
        self,
        bus: Bus,
        *,
        link: str | os.PathLike[str] | None = None,
        follow_baud: bool = True,
        speed: float = 1.0,
    ) -> None:
        self.bus = bus
        self._pty = RawPty(link)
        self.link = self._pty.link
        self.follow_baud = follow_baud
        self.speed = speed
        self._thread: ServerThread | None = None
        self._pump: Pump | None = None
        self.device = ""

    def start(self) -> PtyServer:
        """Create the pseudo-terminal and start serving; returns self."""
        pty = self._pty
        self.device = pty.open()
        self._thread = ServerThread(f"snakebot.sim-pty {self.device}")
        baud = (lambda: tty_baudrate(pty.slave)) if self.follow_baud else None
        self._pump = Pump(
            self.bus,
            pty.master,
            lock=self._thread.lock,
            wake_fd=self._thread.wake_fd,
            baudrate=baud,
            speed=self.speed,
        )
        self._thread.start(self._pump.run)
        return self

    def close(self) -> None:
        """Stop serving and remove the device (and the link)."""
        if self._pump is not None:
            self._pump.stopped = True
        self._stop_thread()
        self._pty.close()
