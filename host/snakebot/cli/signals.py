"""Signals, handled the same way by every command.

* SIGINT (Ctrl-C), SIGTERM (``timeout``, systemd, ``kill``) and SIGHUP (the terminal
  closed) all stop a command by the same road: an exception raised where the program
  is (``KeyboardInterrupt`` for SIGINT, :class:`Terminated`, a subclass of it, for the
  others), so every ``finally`` and ``with`` block runs: recordings are closed
  readable, temporary files removed, ports released, QEMU stopped. The command then
  exits with 128 + the signal's number: 130, 143, 129 (:func:`interrupted_status`).
* The serving commands (``sim serve``, ``sim bus``, ``sim bootloader``) wait for the
  same three signals (:func:`serving`): the one that comes ends the wait, the server
  stops cleanly (its links and sockets removed, QEMU stopped, its last report printed)
  and then exits the same way as any other command, with 130, 143 or 129.
* Ctrl-C while Python is still importing snakebot prints one line, no traceback
  (``snakebot.__main__``).
"""

from __future__ import annotations

import signal
import threading
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


class StopRequest:
    """What a server waits on: set by the first stop signal, which it remembers."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self.signum: int | None = None

    def wait(self, timeout: float) -> bool:
        """Whether a stop signal came, waiting up to ``timeout`` seconds for one."""
        return self._event.wait(timeout)

    def set(self, signum: int) -> None:
        if self.signum is None:
            self.signum = signum
        self._event.set()

    def exit_by_signal(self) -> None:
        """Once the server has stopped cleanly: leave as the signal says (the exception
        the CLI turns into 130, 143 or 129); nothing if none came."""
        if self.signum == signal.SIGINT:
            raise KeyboardInterrupt
        if self.signum is not None:
            _received.append(self.signum)
            raise Terminated(self.signum)


@contextmanager
def serving() -> Iterator[StopRequest]:
    """For the length of the block, the stop signals set the :class:`StopRequest` it
    yields instead of raising where the program is (a server stops between two of its
    steps); the previous handlers come back at its end."""
    stop = StopRequest()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set(signum)

    previous = {s: signal.signal(s, on_signal) for s in STOP_SIGNALS}
    try:
        yield stop
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
