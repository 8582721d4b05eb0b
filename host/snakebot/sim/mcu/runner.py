"""The emulated CM-530 running in real time on a background thread, its PC link on a
pseudo-terminal (or a socket) that host tools open like the board's USB-serial port.

The thread runs the board in steps of :data:`STEP_S` of emulated time (fewer when the PC
sends) and never ahead of the wall clock, so the PC's bytes arrive at the emulated time
they are sent (the board first catches up with the wall clock) and the firmware's replies
leave within a step of when it sends them. Between steps it waits for the PC's bytes. While
the link is quiet (:data:`QUIET_AFTER_S` without a byte either way) the steps are
:data:`QUIET_STEP_S`: the PC's first byte still wakes the thread at once.
Bytes to the PC that the terminal has no room for are dropped and counted, as a USB
adapter drops what the PC does not read. On a pseudo-terminal a client that set
another baud rate than the one USART3 is programmed for is not understood: its bytes are
dropped (counted in :attr:`McuFirmware.wrong_baud`), as a UART at the wrong rate would
garble them.

::

    with McuFirmware(image, bus=bus) as fw:
        print(fw.pc_link)          # /dev/pts/N: snakebot ... --port /dev/pts/N
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import socket
import threading
import time
from types import TracebackType

from snakebot.settings import is_set
from snakebot.sim.bus.bus import Bus
from snakebot.sim.mcu.board import Cm530, Leftovers
from snakebot.sim.mcu.errors import McuMisuse
from snakebot.sim.transports.base import RawPty
from snakebot.sim.transports.pty import tty_baudrate

STEP_S = 0.001
"""The emulated time the thread runs before it looks at the PC link again (less when the
PC's bytes come first)."""

QUIET_STEP_S = 0.01
"""The step while the PC link is quiet: a gait playing on its own needs no look at the link
every millisecond, and each wake-up costs the host far more than the emulated millisecond
(a third of the thread's time at real time went to waking up a thousand times a second)."""

QUIET_AFTER_S = 0.1
"""How long after the link's last byte (either way) the steps stay :data:`STEP_S`: a reply
the firmware sends that long after a request leaves up to a quiet step late."""

PC_BACKLOG = 256
"""The most of the PC's bytes taken off the link ahead of USART3's receiver (44 ms of the
57600 baud line). More stays in the terminal, whose writer then waits, as behind a USB
adapter that passes bytes on at the line's rate: a client that floods the link costs the
emulator no memory."""

MAX_LAG_S = 0.05
"""The most the emulated board falls behind the wall clock. A host too busy to run it in
real time slows its time down instead (counted in :attr:`McuFirmware.slowed_s`): the
firmware sees a consistent clock, and the PC sees a controller that answers late by at
most this much plus the time it needs, never a backlog of seconds."""

BAUD_TOLERANCE = 0.03
"""How far (relative) the client's rate may be from USART3's and still be understood."""


STRICT_ENV = "SNAKEBOT_MCU_STRICT"
"""Set: unmodelled register accesses stop the board (the test suite sets it)."""


class McuFirmware:
    """The board on a thread. ``pc_socket``: serve the PC link on this connected socket
    instead of a new pseudo-terminal (the bootloader hands its line over that way).
    ``link``: a symlink to the pseudo-terminal. ``speed``: emulated seconds per wall
    second. ``strict``: an access to a register no model knows stops the board with
    :class:`~snakebot.sim.mcu.errors.UnmodelledAccess` (kept in :attr:`error`) instead of
    reading as zero, counted; by default as :data:`STRICT_ENV` says."""

    def __init__(
        self,
        image: bytes,
        *,
        bus: Bus | None = None,
        pc_socket: socket.socket | None = None,
        link: str | None = None,
        strict: bool | None = None,
        leftovers: Leftovers | None = None,
        speed: float = 1.0,
    ) -> None:
        strict = is_set(STRICT_ENV) if strict is None else strict
        self.board = Cm530(image, bus=bus, strict=strict, leftovers=leftovers)
        self._socket = pc_socket
        self._pty = None if pc_socket is not None else RawPty(link)
        self.speed = speed
        self.lock = threading.RLock()
        self.dropped = 0
        self.wrong_baud = 0
        self.error: BaseException | None = None
        self.pc_link = ""
        self._fd = -1
        self._wake_r = self._wake_w = -1
        self._thread: threading.Thread | None = None
        self._stop = False
        self.cpu_s = 0.0  # processor time the thread used
        self.slowed_s = 0.0  # wall time the board's clock was held back (host too busy)

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> McuFirmware:
        if self._thread is not None:
            raise McuMisuse("this McuFirmware was already started: make a new one")
        if self._pty is not None:
            self.pc_link = self._pty.open()
            self._fd = self._pty.master
        else:
            assert self._socket is not None
            self._socket.setblocking(False)
            self._fd = self._socket.fileno()
            self.pc_link = "socket"
        self._wake_r, self._wake_w = os.pipe()
        self._thread = threading.Thread(
            target=self._guarded, name=f"snakebot.sim-cm530 {self.pc_link}", daemon=True
        )
        self._thread.start()
        return self

    def _guarded(self) -> None:
        try:
            self._run()
        except BaseException as exc:  # kept for stop() and the caller to report
            self.error = exc

    def _run(self) -> None:
        board = self.board
        wall0 = time.monotonic()
        cpu0 = time.thread_time()
        emu0 = board.now()
        data = b""  # the PC's bytes read while the board waited, sent once it caught up
        last_io = wall0  # the link's last byte, either way (wall clock)
        while not self._stop:
            step = STEP_S if time.monotonic() - last_io < QUIET_AFTER_S else QUIET_STEP_S
            target = emu0 + (time.monotonic() - wall0) * self.speed
            behind = target - board.now()
            if behind > MAX_LAG_S * self.speed:
                slip = (behind / self.speed) - MAX_LAG_S
                wall0 += slip
                self.slowed_s += slip
                target = emu0 + (time.monotonic() - wall0) * self.speed
            with self.lock:
                now = board.now()
                if target > now:
                    board.run_until(min(target, now + step))
                if data or board.pc_out:
                    last_io = time.monotonic()
                    step = STEP_S  # busy again: the answer is not left a quiet step behind
                if data:
                    self._send_input(data)
                    data = b""
                self._flush_out()
                room = PC_BACKLOG - board.mcu.usart3.inbox
                ahead = board.now() - (emu0 + (time.monotonic() - wall0) * self.speed)
            self.cpu_s = time.thread_time() - cpu0
            # the next step when a whole step is due, or at once when the PC sends: run
            # for the time that passed since the last, the loop would spin in steps as
            # short as itself, using a whole core however fast the board runs
            wait = max((ahead + step) / self.speed, 0.0)
            watch = [self._fd, self._wake_r] if room > 0 else [self._wake_r]
            ready, _, _ = select.select(watch, [], [], wait)
            if self._wake_r in ready:
                return
            if self._fd in ready:
                data = self._take_input(room)

    def _take_input(self, most: int) -> bytes:
        """Up to ``most`` of the PC's bytes waiting on the link (none if it has none or
        hung up)."""
        try:
            data = os.read(self._fd, most)
        except BlockingIOError:
            return b""
        except OSError as exc:
            if exc.errno in (errno.EIO, errno.EBADF):
                time.sleep(STEP_S)  # no client has the terminal open
                return b""
            raise
        if not data and self._pty is None:
            self._stop = True  # the socket's other end closed
        return data

    def _send_input(self, data: bytes) -> None:
        """The PC's ``data`` reaches USART3 now, unless the client's rate is not the
        USART's."""
        if self._pty is not None:
            theirs = tty_baudrate(self._pty.slave)
            ours = self.board.mcu.usart3.baud
            if theirs and (not ours or abs(theirs - ours) > BAUD_TOLERANCE * ours):
                self.wrong_baud += len(data)
                return
        self.board.pc_send(data)

    def _flush_out(self) -> None:
        out = self.board.pc_out
        if not out:
            return
        try:
            sent = os.write(self._fd, out)
        except BlockingIOError:
            sent = 0
        except OSError as exc:
            if exc.errno not in (errno.EIO, errno.EBADF, errno.EPIPE):
                raise
            sent = len(out)  # nobody listens: lost, as on the wire
        self.dropped += len(out) - sent
        out.clear()

    def stop(self) -> None:
        """Stop the thread and close the PC link (idempotent)."""
        self._stop = True
        if self._thread is not None:
            if self._wake_w >= 0:
                with contextlib.suppress(OSError):
                    os.write(self._wake_w, b"x")
            self._thread.join(5.0)
            self._thread = None
        for fd in (self._wake_r, self._wake_w):
            if fd >= 0:
                os.close(fd)
        self._wake_r = self._wake_w = -1
        if self._pty is not None:
            self._pty.close()
        if self._socket is not None:
            self._socket.close()

    def __enter__(self) -> McuFirmware:
        if self._thread is None:
            self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
