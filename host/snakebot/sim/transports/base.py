"""What the emulator's servers share: a raw pseudo-terminal that may carry a symlink
(:class:`RawPty`), and the start/close life cycle, usable as a context manager
(:class:`Server`, :class:`ThreadedServer`)."""

from __future__ import annotations

import os
import tty
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

from snakebot.sim.errors import SimFailure
from snakebot.sim.transports.claim import PathClaim
from snakebot.sim.transports.pump import ServerThread

if TYPE_CHECKING:  # typing.Self is 3.11+; annotations are never evaluated at run time
    from typing import Self  # novermin


class RawPty:
    """A pseudo-terminal pair for a server: the slave in raw mode (no echo, no line
    editing: bytes pass untouched), the master non-blocking.

    ``link``: on :meth:`open`, also make a symlink at this path to the device, claimed
    (:class:`~snakebot.sim.transports.claim.PathClaim`): the link a killed server of
    ours left there is replaced; a live server's, or anything someone else made, is
    refused (``link_advice`` ending the error, which is about the parameter
    ``link_param``). :meth:`close` removes it if it is still ours. The server keeps the
    slave open itself, so clients may open and close the device as often as they like.
    """

    def __init__(
        self,
        link: str | os.PathLike[str] | None = None,
        *,
        link_advice: str = "choose another path",
        link_param: str = "link",
    ) -> None:
        self.link = Path(link) if link else None
        self.link_advice = link_advice
        self.link_param = link_param
        self.master = self.slave = -1
        self.device = ""
        self._claim: PathClaim | None = None

    def open(self) -> str:
        """Create the pseudo-terminal (and the link); returns the device path."""
        claim = None
        if self.link is not None:
            claim = PathClaim(self.link, advice=self.link_advice, param=self.link_param)
            claim.acquire()  # before the pty: a refusal leaves nothing to undo
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.device = os.ttyname(self.slave)
        if claim is not None:
            self._claim = claim
            self._make_link(claim)
        return self.device

    def release_slave(self) -> None:
        """Stop holding the device open: from now on, once every client has closed it,
        reading the master fails (EIO on Linux) until a client opens it again."""
        if self.slave >= 0:
            os.close(self.slave)
            self.slave = -1

    def close(self) -> None:
        """Close both ends and remove the link (if it is still the one made)."""
        for fd in (self.master, self.slave):
            if fd >= 0:
                os.close(fd)
        self.master = self.slave = -1
        if self._claim is not None:
            self._claim.release()
            self._claim = None

    def _make_link(self, claim: PathClaim) -> None:
        try:
            claim.path.symlink_to(self.device)
            claim.made()
        except OSError as exc:
            self.close()
            raise SimFailure(f"cannot make the link {claim.path}: {exc.strerror or exc}") from None


class Server:
    """A server that :meth:`start` sets serving on ``_thread`` and :meth:`close` stops.
    ``with server:`` starts it unless it was started already, and closes it at the end."""

    _thread: object | None = None

    def start(self) -> Self:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def __enter__(self) -> Self:
        return self.start() if self._thread is None else self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class ThreadedServer(Server):
    """A :class:`Server` whose thread is a :class:`ServerThread`."""

    _thread: ServerThread | None = None

    @property
    def lock(self) -> object:
        """Hold this while touching what the server serves from another thread."""
        assert self._thread is not None, "start() first"
        return self._thread.lock

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.alive

    def _stop_thread(self) -> None:
        """Wake the serving thread, wait for it, and forget it."""
        if self._thread is not None:
            self._thread.stop()
            self._thread = None
