"""Signals, handled the same way by every command.

* SIGINT (Ctrl-C), SIGTERM (``timeout``, systemd, ``kill``) and SIGHUP (the terminal
  closed) all stop a command by the same road: an exception raised where the program
  is (``KeyboardInterrupt`` for SIGINT, :class:`Terminated`, a subclass of it, for the
  others), so every ``finally`` and ``with`` block runs: recordings are closed
  readable, temporary files removed, ports released, QEMU stopped. The command then
  exits with 128 + the signal's number: 130, 143, 129 (:func:`interrupted_status`).
* The serving commands (``sim serve``, ``sim bus``, ``sim bootloader``) catch the same
  three signals with their own handlers (:data:`STOP_SIGNALS`), since stopping is how a
  server ends its work: they stop cleanly and exit 0.
* Ctrl-C while Python is still importing snakebot prints one line, no traceback
  (``snakebot.__main__``).
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

TERMINATING = (signal.SIGTERM, signal.SIGHUP)
"""The signals turned into :class:`Terminated` (SIGINT is Python's KeyboardInterrupt)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived; ``signum`` says which."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


_received: list[int] = []
"""The terminating signals received so far, for commands that caught the interrupt to
finish their work before they exit."""


def _raise(signum: int, frame: FrameType | None) -> None:
    _received.append(signum)
    raise Terminated(signum)


def install() -> None:
    """Turn SIGTERM and SIGHUP into :class:`Terminated` for the rest of the process,
    where nobody has set a handler of their own (an embedding program keeps its own)."""
    for signum in TERMINATING:
        try:
            if signal.getsignal(signum) is signal.SIG_DFL:
                signal.signal(signum, _raise)
        except ValueError:  # not the main thread: leave signals to whoever owns it
            return


@contextmanager
def held() -> Iterator[None]:
    """Hold the stop signals back for the length of the block (a sample being written:
    a row is never cut in half); one that arrived meanwhile is delivered at its end."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:  # not POSIX: no holding, the signal lands where it lands
        yield
        return
    before = mask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, before)


def interrupted_status(exc: BaseException | None = None) -> int:
    """128 + the number of the signal that ``exc`` (or what it wraps: click's ``Abort``
    wraps the interrupt) stands for; without ``exc``, of the last SIGTERM or SIGHUP
    received; 130 (SIGINT) when it is a plain interrupt."""
    if exc is None:
        return 128 + (_received[-1] if _received else signal.SIGINT)
    seen = 0
    while exc is not None and seen < 8:
        if isinstance(exc, Terminated):
            return 128 + exc.signum
        if isinstance(exc, KeyboardInterrupt):
            break
        exc = exc.__cause__ or exc.__context__
        seen += 1
    return 128 + signal.SIGINT
