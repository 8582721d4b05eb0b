"""The loop that connects an emulated bus to a byte stream (a pty master, a socket).

The bus clock follows the wall clock (``snakesim.clock.WallClockPacer``): bytes read
from the client go on the wire at the moment they arrive, and bytes for the client are
handed over when the emulated wire has delivered them, so a client's reply timeouts
mean what they do on real hardware. Between events the thread sleeps in ``select``.
"""

from __future__ import annotations

import errno
import os
import select
import threading
from collections.abc import Callable

from snakesim.bus import Bus
from snakesim.clock import WallClockPacer

IDLE_WAKE_S = 0.05
"""Longest sleep when the bus has nothing scheduled (it keeps the clock moving)."""

READ_CHUNK = 4096


class Pump:
    """Runs ``bus`` against the stream on file descriptor ``fd`` until stopped or the
    stream ends. ``baudrate`` (optional) tells the master's current rate, e.g. read from
    the pty's termios; ``lock`` guards the bus against other users."""

    def __init__(
        self,
        bus: Bus,
        fd: int,
        *,
        lock: threading.RLock,
        wake_fd: int,
        baudrate: Callable[[], float | None] | None = None,
        speed: float = 1.0,
    ) -> None:
        self.bus = bus
        self.fd = fd
        self.lock = lock
        self.wake_fd = wake_fd
        self.baudrate = baudrate
        self.pacer = WallClockPacer(speed)
        self.stopped = False
        self.overruns = 0

    def _send(self, data: bytes) -> bool:
        """Hand ``data`` to the client; False when the stream has ended."""
        view = memoryview(data)
        while view:
            try:
                n = os.write(self.fd, view)
            except BlockingIOError:
                self.overruns += len(view)  # the client is not reading: bytes are lost
                return True
            except OSError as exc:
                if exc.errno in (errno.EIO, errno.EPIPE, errno.ECONNRESET, errno.EBADF):
                    return False
                raise
            view = view[n:]
        return True

    def run(self) -> None:
        """Serve until :attr:`stopped` is set or the client's stream ends."""
        bus = self.bus
        pacer = self.pacer
        with self.lock:
            pacer.anchor(bus.now)
        while not self.stopped:
            with self.lock:
                bus.run_until(pacer.now())
                out = bus.master_read(1 << 20)
                # wake for the next event, or when everything on its way to the client
                # has arrived (bytes go over in bursts, as from a USB adapter)
                upcoming = [
                    t
                    for t in (bus.next_master_arrival(1 << 20), bus.next_event_time())
                    if t is not None
                ]
            if out and not self._send(out):
                return
            wait = IDLE_WAKE_S
            if upcoming:
                wait = min(wait, pacer.wall_delay(min(upcoming)))
            try:
                ready, _, _ = select.select([self.fd, self.wake_fd], [], [], wait)
            except (OSError, ValueError):
                return
            if self.wake_fd in ready:
                return
            if self.fd in ready:
                try:
                    data = os.read(self.fd, READ_CHUNK)
                except BlockingIOError:
                    continue
                except OSError as exc:
                    if exc.errno in (errno.EIO, errno.ECONNRESET, errno.EBADF):
                        return
                    raise
                if not data:
                    return
                baud = self.baudrate() if self.baudrate else None
                with self.lock:
                    if baud:
                        bus.baudrate = baud
                    bus.run_until(pacer.now())
                    bus.master_write(data)
                    # Nothing the client sends now can reach the wire before these bytes
                    # are out, so the bus may run that far ahead of the wall clock: the
                    # servos take the instruction at once and the reply is scheduled
                    # without another wake-up. (A later write starts at most that late.)
                    bus.run_until(bus.master_tx_done)


class ServerThread:
    """A daemon thread running pumps, stopped through a self-pipe."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._wake_r, self._wake_w = os.pipe()
        self._thread: threading.Thread | None = None
        self.lock = threading.RLock()
        self.error: BaseException | None = None

    @property
    def wake_fd(self) -> int:
        return self._wake_r

    def start(self, target: Callable[[], None]) -> None:
        def guarded() -> None:
            try:
                target()
            except BaseException as exc:  # reported by stop()
                self.error = exc

        self._thread = threading.Thread(target=guarded, name=self.name, daemon=True)
        self._thread.start()

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def stop(self, timeout: float = 5.0) -> None:
        """Wake the thread, wait for it, and close the pipe."""
        if self._wake_w >= 0:
            try:
                os.write(self._wake_w, b"x")
            except OSError:
                pass
        if self._thread is not None:
            self._thread.join(timeout)
        for fd in (self._wake_r, self._wake_w):
            if fd >= 0:
                os.close(fd)
        self._wake_r = self._wake_w = -1
