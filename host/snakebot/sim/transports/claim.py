"""A server's claim on a path it makes for its clients: a ``--link`` symlink to its
pseudo-terminal, a ``--unix`` socket.

A server that is killed (SIGKILL, a crash, a power cut of the terminal) leaves that path
behind, and the next start must tell such a leftover from a path someone else made (a
file, a link of theirs, a socket of another program) or one a running server still
uses. So the claim is recorded where only this user can write (``snakebot.rundir``,
``snakebot-links``): one record file per path, held with ``flock`` for as long as the
server lives (the kernel lets go of it when the process ends, however it ends) and
naming the server's pid and the very file it made (device and inode, owner, target). A
server that stops cleanly removes both the file and its record; a killed one leaves
them for the next start.

On the next start, a held record means a live server: refused. A free record whose file
is still at the path, unchanged, is a dead server's leftover: replaced. Anything else at
the path (no record, or another file than the recorded one) was not made by a server of
ours and is refused, untouched.
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import os
import stat
import sys
from pathlib import Path

from snakebot.rundir import private_dir
from snakebot.sim.errors import SimInputError

CLAIM_DIR_NAME = "snakebot-links"
"""The private directory (``snakebot.rundir``) of the claim records."""

_OPEN_FLAGS = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
_RECORD_MAX = 4096
_RETRIES = 5


def _absolute(path: Path) -> str:
    """``path`` with its directory resolved (the last part stays as it is: it is the
    link itself), so two spellings of one path share a record."""
    path = Path(os.path.abspath(path))
    return os.path.join(os.path.realpath(path.parent), path.name)


def _identity(info: os.stat_result, target: str) -> str:
    """What identifies the file a server made: its kind, device, inode, owner and (for a
    link) where it points."""
    kind = "link" if stat.S_ISLNK(info.st_mode) else "socket"
    return f"{kind} {info.st_dev} {info.st_ino} {info.st_uid} {target}"


def _describe(path: Path, info: os.stat_result) -> str:
    if stat.S_ISLNK(info.st_mode):
        return f"is a symlink to {os.readlink(path)}"
    if stat.S_ISSOCK(info.st_mode):
        return "is a socket"
    if stat.S_ISDIR(info.st_mode):
        return "is a directory"
    return "exists and is not a link"


class PathClaim:
    """The claim of this process on ``path`` (see the module docstring).

    :meth:`acquire` before making the file (it removes a dead server's leftover, refuses
    anything else there with ``advice`` ending the error), :meth:`made` once it is made,
    :meth:`release` when the server stops (removes the file if it is still the one made).
    ``param``: the parameter ``path`` came through, which a refusal is ``about``.
    """

    def __init__(self, path: str | os.PathLike[str], *, advice: str, param: str) -> None:
        self.path = Path(path)
        self.advice = advice
        self.param = param
        self._key = _absolute(self.path)
        self._fd = -1
        self._record: Path | None = None
        self._made = ""

    def _record_path(self) -> Path:
        digest = hashlib.sha256(self._key.encode(errors="surrogateescape")).hexdigest()[:32]
        return private_dir(CLAIM_DIR_NAME) / f"{digest}.claim"

    def _refuse(self, what: str, fix: str) -> SimInputError:
        return SimInputError(f"{self.path} {what}: {fix} {self.advice}").about(self.param)

    def acquire(self) -> None:
        """Hold the record of ``path`` and clear a dead server's leftover there;
        :class:`SimInputError` if a live server holds it or a file not of ours is there."""
        record = self._record_path()
        for _ in range(_RETRIES):
            fd = self._open_record(record)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                holder = _read(fd).split("\n", 1)[0]
                os.close(fd)
                raise self._refuse(
                    f"is in use by a running snakebot server ({holder or 'pid unknown'})",
                    "stop that server first, or",
                ) from None
            if _same_file(fd, record):
                break
            os.close(fd)  # its holder removed it as it stopped: take the new one
        else:
            raise self._refuse("is being claimed by other servers over and over", "wait, or")
        self._fd, self._record = fd, record
        try:
            self._clear_leftover(_read(fd))
        except BaseException:
            self.release()
            raise
        os.ftruncate(fd, 0)
        os.pwrite(fd, self._holder().encode(), 0)

    def _open_record(self, record: Path) -> int:
        try:
            fd = os.open(record, _OPEN_FLAGS, 0o600)
        except OSError as exc:
            problem = "is a symbolic link" if exc.errno == errno.ELOOP else exc.strerror
            raise self._refuse(
                f"cannot be claimed: its record {record} {problem}", f"remove it (rm {record}) or"
            ) from None
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode) or info.st_uid != os.geteuid() or info.st_nlink != 1:
            os.close(fd)
            raise self._refuse(
                f"cannot be claimed: its record {record} is not a regular file of yours "
                "with one link (someone may have planted it)",
                f"remove it (rm {record}) or",
            )
        return fd

    def _holder(self) -> str:
        name = " ".join(Path(a).name for a in sys.argv[:3])
        return f"pid {os.getpid()}: {name}\n{self._key}\n{self._made}\n"

    def _clear_leftover(self, record: str) -> None:
        try:
            info = os.lstat(self.path)
        except FileNotFoundError:
            return
        lines = record.split("\n")
        made = lines[2] if len(lines) > 2 and lines[1] == self._key else ""
        target = os.readlink(self.path) if stat.S_ISLNK(info.st_mode) else ""
        if made and made == _identity(info, target):
            self.path.unlink()  # the very file a server of ours made, and that server is gone
            return
        raise self._refuse(
            f"{_describe(self.path, info)}, which no snakebot server made (or it was "
            "replaced since)",
            f"remove it if it is yours (rm {self.path}), or",
        )

    def made(self) -> None:
        """Record the file just made at ``path`` as this server's."""
        info = os.lstat(self.path)
        target = os.readlink(self.path) if stat.S_ISLNK(info.st_mode) else ""
        self._made = _identity(info, target)
        if self._fd >= 0:
            os.ftruncate(self._fd, 0)
            os.pwrite(self._fd, self._holder().encode(), 0)

    def release(self) -> None:
        """Remove the file made at ``path`` if it is still the one made, and let go of
        the record."""
        if self._made:
            try:
                info = os.lstat(self.path)
                target = os.readlink(self.path) if stat.S_ISLNK(info.st_mode) else ""
                if _identity(info, target) == self._made:
                    self.path.unlink()  # still ours: one put there since is left alone
            except OSError:
                pass
            self._made = ""
        if self._fd >= 0:
            if self._record is not None and _same_file(self._fd, self._record):
                self._record.unlink()  # still locked: no one else holds it meanwhile
            os.close(self._fd)  # closing the descriptor releases the flock
            self._fd, self._record = -1, None


def _read(fd: int) -> str:
    return os.pread(fd, _RECORD_MAX, 0).decode(errors="replace")


def _same_file(fd: int, path: Path) -> bool:
    """Whether the open ``fd`` is still the file at ``path`` (not one removed since)."""
    try:
        there = os.stat(path, follow_symlinks=False)
    except OSError:
        return False
    here = os.fstat(fd)
    return (here.st_dev, here.st_ino) == (there.st_dev, there.st_ino)
