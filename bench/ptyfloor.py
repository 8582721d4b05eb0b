"""The floor a client can reach on a pseudo-terminal: a bare loop of os.write and
os.read, no serial library, no flush, no parsing (shared by the benchmarks that
measure clients on a pty; not a benchmark itself)."""

from __future__ import annotations

import os
import select
import termios
import time
import tty


def bare_rate(device: str, request: bytes, reply_len: int, n: int, spin: bool) -> float:
    """Transactions per second on ``device`` at 1 Mbps: write ``request``, wait for
    ``reply_len`` bytes (in ``select``, or ``spin``: polling a non-blocking read, as
    dynamixel-sdk does), ``n`` times after one to warm up."""
    fd = os.open(device, os.O_RDWR | os.O_NOCTTY | (os.O_NONBLOCK if spin else 0))
    try:
        tty.setraw(fd)
        attrs = termios.tcgetattr(fd)
        attrs[4] = attrs[5] = termios.B1000000
        termios.tcsetattr(fd, termios.TCSANOW, attrs)
        termios.tcflush(fd, termios.TCIFLUSH)

        def transaction() -> None:
            os.write(fd, request)
            got = 0
            # generous: on a loaded machine the device may wait a while for a core
            deadline = time.monotonic() + 5.0
            while got < reply_len:
                if time.monotonic() > deadline:
                    raise RuntimeError(f"no reply from {device}")
                if spin:
                    try:
                        got += len(os.read(fd, reply_len - got))
                    except BlockingIOError:
                        pass
                elif select.select([fd], [], [], 1.0)[0]:
                    got += len(os.read(fd, reply_len - got))

        transaction()
        start = time.perf_counter()
        for _ in range(n):
            transaction()
        return n / (time.perf_counter() - start)
    finally:
        os.close(fd)
