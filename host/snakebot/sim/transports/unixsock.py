"""An emulated bus on a Unix-domain stream socket, for QEMU's character devices.

Listening (the default) suits ``qemu-system-arm -serial unix:PATH,server=off`` or
``-chardev socket,id=bus,path=PATH,server=off``: start this server first, then QEMU
connects to it. Connecting (``connect=True``) suits a QEMU that listens itself
(``-chardev socket,path=PATH,server=on,wait=off``). Either way one client is served at
a time; when it disconnects, a listening server waits for the next one.

QEMU's USART model does not carry a baud rate, so the master's rate is the bus's own
(``bus.baudrate``, 1 Mbps unless changed).
"""

from __future__ import annotations

import os
import select
import socket
import time
from pathlib import Path

from snakebot.sim.bus.bus import Bus
from snakebot.sim.errors import SimFailure
from snakebot.sim.transports.base import ThreadedServer
from snakebot.sim.transports.claim import PathClaim
from snakebot.sim.transports.pump import Pump, ServerThread

CONNECT_TIMEOUT_S = 10.0
"""How long a connecting server keeps trying to reach a listening QEMU."""


class UnixSocketServer(ThreadedServer):
    """Serves ``bus`` on the Unix socket ``path`` from a background thread.

    A listening server claims its path (:class:`~snakebot.sim.transports.claim.PathClaim`:
    a socket a killed server of ours left is replaced, anything else refused), unless
    ``private``: the path is in a fresh directory of this process's own, where nothing
    can be left and nobody else can write. ``param``: the parameter ``path`` came through
    (a refusal of the path is about it)."""

    def __init__(
        self,
        bus: Bus,
        path: str | os.PathLike[str],
        *,
        connect: bool = False,
        speed: float = 1.0,
        private: bool = False,
        param: str = "unix_path",
    ) -> None:
        self.bus = bus
        self.param = param
        self.path = Path(path)
        self.connect = connect
        self.private = private
        self.speed = speed
        self._listener: socket.socket | None = None
        self._thread: ServerThread | None = None
        self._pump: Pump | None = None
        self._claim: PathClaim | None = None
        self.connections = 0

    def start(self) -> UnixSocketServer:
        """Listen (or connect) and start serving; returns self."""
        if not self.connect:
            claim = (
                None
                if self.private
                else PathClaim(self.path, advice="choose another path", param=self.param)
            )
            if claim is not None:
                claim.acquire()  # a dead server's socket goes; a live one's or another's stays
            listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            try:
                listener.bind(str(self.path))
                if claim is not None:
                    claim.made()
            except OSError as exc:
                listener.close()
                if claim is not None:
                    claim.release()
                raise SimFailure(
                    f"cannot listen on {self.path}: {exc.strerror or exc}: check the directory"
                ) from exc
            listener.listen(1)
            self._listener = listener
            self._claim = claim
        self._thread = ServerThread(f"snakebot.sim-unix {self.path}")
        self._thread.start(self._serve)
        return self

    def _dial(self) -> socket.socket | None:
        deadline = time.monotonic() + CONNECT_TIMEOUT_S
        while time.monotonic() < deadline:
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            try:
                s.connect(str(self.path))
                return s
            except OSError:
                s.close()
            ready, _, _ = select.select([self._thread.wake_fd], [], [], 0.05)
            if ready:
                return None
        raise SimFailure(f"nothing listens on {self.path}: start QEMU first, or listen instead")

    def _serve(self) -> None:
        assert self._thread is not None
        wake = self._thread.wake_fd
        while True:
            if self.connect:
                conn = self._dial()
                if conn is None:
                    return
            else:
                assert self._listener is not None
                ready, _, _ = select.select([self._listener, wake], [], [])
                if wake in ready:
                    return
                conn, _ = self._listener.accept()
            self.connections += 1
            conn.setblocking(False)
            try:
                self._pump = Pump(
                    self.bus,
                    conn.fileno(),
                    lock=self._thread.lock,
                    wake_fd=wake,
                    speed=self.speed,
                )
                self._pump.run()
            finally:
                conn.close()
            if self._pump.stopped or self.connect:
                return
            ready, _, _ = select.select([wake], [], [], 0)
            if ready:
                return

    def close(self) -> None:
        """Stop serving, close the socket and remove its file."""
        if self._pump is not None:
            self._pump.stopped = True
        self._stop_thread()
        if self._listener is not None:
            self._listener.close()
            self._listener = None
            if self.private:
                self.path.unlink(missing_ok=True)  # in our own directory: surely ours
        if self._claim is not None:
            self._claim.release()  # removes the socket if it is still the one made
            self._claim = None
