"""Writing an instruction and reading its reply with as few system calls as the port allows.

A transaction's critical path is the time between the reply's last byte arriving and the
next instruction leaving; at 1 Mbps the wire itself needs only 160 us for a READ, so a
few microseconds there matter. pyserial's POSIX port costs more than the operating
system requires: every ``write`` is followed by a ``select`` that waits for the bytes
to drain, every ``read`` builds timeout bookkeeping, and setting ``timeout`` re-applies
the whole termios configuration. On such a port :class:`PortIO` writes with one
``os.write`` and reads with one ``select`` and one ``os.read`` (a read that times out
polls its last moments, :data:`POLLED_TAIL_S`), on the file descriptor
pyserial opened (pyserial still owns it: opening, settings, closing). Any other port
(``sim://``, ``loop://``, sockets, a port handed in by the caller of another kind) goes
through pyserial unchanged; a port whose class has an ``exchange`` method of its own
(``sim://``) does a transaction's first round (flush, write, timed read) in one call.
"""

from __future__ import annotations

import os
import select
import termios
import time
from collections.abc import Callable

import serial
from serial import SerialException

try:
    from serial.serialposix import Serial as _PosixSerial
except ImportError:  # not a POSIX system: every port takes the general path
    _PosixSerial = None

TIMEOUT_TOLERANCE_S = 1e-4
"""A read timeout that differs by less than this from the port's is not re-applied."""

POLLED_TAIL_S = 2e-4
"""The last stretch of a timed read that is polled rather than slept through. A thread
asleep in ``select`` wakes 50-150 us after its timeout (the kernel's timer slack, then
the scheduler), and a bus scan ends one such wait per silent ID: at 1 Mbps, where a
silent ID needs about 0.6 ms of wire and return delay, that is a sixth more per ID.
Polling costs CPU only in this tail, and only when nothing arrives before it."""


class PortIO:
    """Write and timed read on ``port``, direct on a plain POSIX serial port.

    :attr:`clock` is what a reply's deadline is counted on: the wall clock, or the port's
    own where it has one (``port_clock``: an emulated bus with a clock of its own, whose
    replies are due in its time however late the host runs the client)."""

    __slots__ = ("port", "_direct", "_exchange", "clock")

    def __init__(self, port: serial.SerialBase) -> None:
        self.port = port
        self.clock: Callable[[], float] = getattr(port, "port_clock", time.monotonic)
        # Only pyserial's plain POSIX class: its descriptor is non-blocking and read with
        # select, exactly as done here (subclasses such as VTIMESerial read otherwise).
        self._direct = _PosixSerial is not None and type(port) is _PosixSerial
        # A port whose class does a transaction's first round itself (the emulator's
        # sim://; not a wrapper that forwards attributes, which would see none of it)
        own = getattr(type(port), "exchange", None)
        self._exchange: Callable[[serial.SerialBase, bytes, int], bytes] | None = (
            own if callable(own) else None
        )

    def write(self, data: bytes) -> None:
        """Put ``data`` on the port (the whole of it)."""
        port = self.port
        if not self._direct or not port.is_open:
            port.write(data)
            return
        try:
            n = os.write(port.fd, data)
        except BlockingIOError:
            n = 0
        except OSError as exc:
            raise SerialException(f"write failed: {exc}") from exc
        if n < len(data):
            port.write(data[n:])  # the output queue is full: let pyserial wait for room

    def flush_input(self) -> None:
        """Discard what has arrived and not been read."""
        port = self.port
        if not self._direct or not port.is_open:
            port.reset_input_buffer()
            return
        try:
            termios.tcflush(port.fd, termios.TCIFLUSH)
        except termios.error as exc:
            raise SerialException(f"flush failed: {exc}") from exc

    def exchange(self, packet: bytes, size: int, timeout: float) -> bytes:
        """A transaction's first round in one call: discard what has arrived, write
        ``packet``, and :meth:`read` up to ``size`` bytes within ``timeout`` seconds."""
        port = self.port
        if self._direct and port.is_open:
            self.flush_input()
            self.write(packet)
        elif self._exchange is not None:
            _set_timeout(port, timeout)
            return self._exchange(port, packet, size)
        else:
            port.reset_input_buffer()
            port.write(packet)
        return self.read(size, timeout)

    def read(self, size: int, timeout: float) -> bytes:
        """Up to ``size`` bytes, waiting at most ``timeout`` seconds for the first."""
        port = self.port
        if not self._direct or not port.is_open:
            _set_timeout(port, timeout)
            return port.read(size)
        fd = port.fd
        try:
            if not _wait_readable(fd, timeout):
                return b""
            data = os.read(fd, size)
        except BlockingIOError:
            return b""
        except OSError as exc:
            raise SerialException(f"read failed: {exc}") from exc
        if not data:
            raise SerialException(
                "the port reports data but reading returns none (device disconnected, or "
                "another program has the port open?)"
            )
        return data


def _set_timeout(port: serial.SerialBase, timeout: float) -> None:
    """``port``'s read timeout ``timeout``, unless it is that already (within
    :data:`TIMEOUT_TOLERANCE_S`)."""
    current = port.timeout
    if current is None or abs(current - timeout) > TIMEOUT_TOLERANCE_S:
        port.timeout = timeout


def _wait_readable(fd: int, timeout: float) -> bool:
    """Whether ``fd`` becomes readable within ``timeout`` seconds: asleep in ``select``
    until :data:`POLLED_TAIL_S` before the end, then polling, so that a wait which
    finds nothing ends on time instead of a scheduler's wake-up later."""
    deadline = time.monotonic() + timeout
    sleep = timeout - POLLED_TAIL_S
    if sleep > 0 and select.select((fd,), (), (), sleep)[0]:
        return True
    while True:
        if select.select((fd,), (), (), 0)[0]:
            return True
        if time.monotonic() >= deadline:
            return False
