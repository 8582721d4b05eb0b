"""The loop that connects an emulated bus to a byte stream (a pty master, a socket).

The bus clock follows the wall clock (``snakebot.sim.bus.clock.WallClockPacer``): bytes read
from the client go on the wire at the moment they arrive, and bytes for the client are
handed over when the emulated wire has delivered them, so a client's reply timeouts
mean what they do on real hardware. Packets that reach the pump together go out one
after the other as the line allows: each after the replies to those before it are in
(see :meth:`Pump._feed`). Between events the thread sleeps in ``select``;
as the kernel wakes sleepers late (Linux by its 50 us timer slack, which the thread
lowers, and a virtual machine by tens of microseconds more), it sleeps short by the
lateness it has seen and polls the last stretch, so bytes go out on time.
"""

from __future__ import annotations

import ctypes
import errno
import os
import select
import sys
import threading
import time
from collections import deque
from collections.abc import Callable

from snakebot.sim.bus.bus import Bus
from snakebot.sim.bus.clock import WallClockPacer
from snakebot.sim.bus.delivery import frame_ends

IDLE_WAKE_S = 0.05
"""Longest sleep when the bus has nothing scheduled (it keeps the clock moving)."""

READ_CHUNK = 4096

MAX_WAKE_LATENESS_S = 0.0002
"""The most a pump sleeps short of a deadline (and polls instead) to make up for the
kernel waking it late."""

BURST_WINDOW_S = 1e-4
"""Longest a byte that has reached the master waits for the rest of its burst: bytes that
follow each other closely (a status packet at 1 Mbps) go over in one piece, as from a
USB adapter, but at a slow rate each goes as it arrives, as from an adapter with a low
latency timer, so a client hears a reply begin (a scan's wait ends at a first byte)."""

LATENESS_SMOOTHING = 0.1
"""Weight of the newest measurement in the running average of that lateness."""

TIMER_SLACK_NS = 1000
"""How late (at most, nanoseconds) the kernel may wake a server thread for its own
convenience; Linux's default, 50 us, would delay every paced reply by that much."""

_PR_SET_TIMERSLACK = 29  # linux/prctl.h


def precise_timers() -> None:
    """Ask Linux to wake the calling thread close to the times it sleeps until (its
    timer slack down to :data:`TIMER_SLACK_NS`); elsewhere, or if that fails, nothing."""
    if not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_TIMERSLACK, TIMER_SLACK_NS, 0, 0, 0)
    except (OSError, AttributeError):
        pass


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
        self._late = 0.0  # how late the kernel wakes this thread, on average (seconds)
        self._backlog: deque[bytes] = deque()  # the client's packets not yet on the wire

    def _sleep(self, fds: list[int], delay: float) -> list[int]:
        """Wait until one of ``fds`` is readable (return those) or ``delay`` seconds
        have passed (return []). Kernels wake a sleeper tens of microseconds late, which
        would deliver every paced byte that late: so sleep short by the lateness seen so
        far and poll the rest of the way."""
        early = min(self._late, delay)
        start = time.monotonic()
        ready, _, _ = select.select(fds, [], [], delay - early)
        if ready:
            return ready
        now = time.monotonic()
        late = min(now - start - (delay - early), MAX_WAKE_LATENESS_S)
        self._late += (late - self._late) * LATENESS_SMOOTHING
        deadline = start + delay
        while now < deadline:
            ready, _, _ = select.select(fds, [], [], 0)
            if ready:
                return ready
            now = time.monotonic()
        return []

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

    def _feed(self, first: bool) -> None:
        """Put the client's packets waiting here on the wire (the lock held): the
        ``first`` at once, each further one once nothing is on its way to the client.

        A client sends an instruction and waits for its reply (or its time) before the
        next, so on a real line its packets never meet the replies they ask for. Here
        the pump may read several at once: the client's writes pile up in the terminal
        while this process or the kernel's tty work is scheduled late (beside busy
        processes, by tens to hundreds of milliseconds). Put on the wire back to back,
        the later ones would collide with the replies to the earlier, damage that no
        bus with that client on it would see. A servo that does not answer leaves the
        line quiet, so packets nobody answers still go back to back."""
        bus = self.bus
        backlog = self._backlog
        while backlog:
            if not first:
                arrival = bus.next_master_arrival(1 << 20)
                if arrival is not None and arrival > bus.now:
                    return
            bus.master_write(backlog.popleft())
            # Nothing the client sends now can reach the wire before these bytes are
            # out, so the bus may run that far ahead of the wall clock: the servos take
            # the instruction at once and the reply is scheduled without another
            # wake-up. (A later write starts at most that late.)
            bus.run_until(bus.master_tx_done)
            first = False

    def _take(self, data: bytes) -> None:
        """The client's ``data``, packet by packet, onto the bus (the lock held)."""
        first = not self._backlog
        start = 0
        for end in frame_ends(data):
            if end > start:
                self._backlog.append(data[start:end])
            start = end
        self._feed(first)

    def run(self) -> None:
        """Serve until :attr:`stopped` is set or the client's stream ends."""
        bus = self.bus
        pacer = self.pacer
        with self.lock:
            pacer.anchor(bus.now)
        precise_timers()
        while not self.stopped:
            with self.lock:
                bus.run_until(pacer.now())
                if self._backlog:
                    self._feed(False)
                out = bus.master_read(1 << 20)
            if out and not self._send(out):  # first the client, then the bookkeeping
                return
            with self.lock:
                # wake for the next event, or when everything on its way to the client
                # has arrived (bytes go over in bursts, as from a USB adapter), or a
                # burst window after the next byte does
                arrival = bus.next_master_arrival(1 << 20)
                if arrival is not None:
                    first = bus.next_master_arrival(1)
                    if first is not None:
                        arrival = min(arrival, first + BURST_WINDOW_S)
                event = bus.next_event_time()
            wait = IDLE_WAKE_S
            if arrival is not None or event is not None:
                upcoming = min(t for t in (arrival, event) if t is not None)
                wait = min(wait, pacer.wall_delay(upcoming))
            try:
                ready = self._sleep([self.fd, self.wake_fd], wait)
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
                    self._take(data)


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
