"""One program per port: an advisory lock file per device that names its holder.

The lock files live in a directory only this user can write (``snakebot.rundir``:
``$XDG_RUNTIME_DIR/snakebot-ports``, else ``<tmp>/snakebot-ports-<uid>``, 0700, its
owner and mode checked). A lock file is opened with ``O_NOFOLLOW`` and used only if it
is a regular file of this user's with one link, so a symbolic or hard link planted in
its place is refused, never followed and never truncated.
"""

from __future__ import annotations

import errno
import os
import stat
import sys
from pathlib import Path

from snakebot.link.transport.errors import PortError
from snakebot.rundir import UnsafeDirectory, private_dir

LOCK_DIR_NAME = "snakebot-ports"
"""The private directory (``snakebot.rundir``) of the lock files."""

_OPEN_FLAGS = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | os.O_NONBLOCK
_OPEN_FLAGS |= getattr(os, "O_CLOEXEC", 0)


def lock_name(device: str) -> str:
    """The name of ``device``'s lock file: the device file's identity (its filesystem and
    inode), so that a symlink (``sim bus --link /tmp/ttyDXL``) and its target share a
    lock, and two ptys of one number in separate pty filesystems (containers sharing a
    temporary folder) have one each; a device that does not exist (opening it fails with
    its own message) by its real path."""
    real = os.path.realpath(device)
    try:
        info = os.stat(real)
    except OSError:
        return (real.strip("/").replace("/", "_") or "root") + ".lock"
    return f"dev{info.st_dev:x}-ino{info.st_ino}.lock"


def lock_path(device: str) -> Path:
    """The lock file of ``device`` (:func:`lock_name`) in the private directory."""
    try:
        where = private_dir(LOCK_DIR_NAME)
    except UnsafeDirectory as exc:
        raise PortError(device, f"cannot lock serial port {device}: {exc}") from None
    return where / lock_name(device)


def _open_lock_file(device: str, path: Path) -> int:
    try:
        fd = os.open(path, _OPEN_FLAGS, 0o600)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            problem = "is a symbolic link"
        else:
            raise PortError(
                device, f"cannot make the lock file {path} of {device}: {exc.strerror or exc}"
            ) from None
    else:
        info = os.fstat(fd)
        if stat.S_ISREG(info.st_mode) and info.st_uid == os.geteuid() and info.st_nlink == 1:
            return fd
        os.close(fd)
        problem = "is not a regular file of yours with one link"
    raise PortError(
        device,
        f"the lock file {path} of {device} {problem}, which snakebot never writes through: "
        f"someone may have planted it; remove it (rm {path}) and try again",
    )


class PortLock:
    """An advisory lock on a device, held for as long as the port is open: a lock file
    locked with ``flock`` (released by the kernel when the process ends, however it ends)
    that names the holder, so a second opener can say who has the port."""

    def __init__(self, device: str) -> None:
        import fcntl  # POSIX only; Windows opens a COM port exclusively by itself

        self.path = lock_path(device)
        self._fd = _open_lock_file(device, self.path)
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.pread(self._fd, 512, 0).decode(errors="replace").strip()
            os.close(self._fd)
            raise PortError(
                device,
                f"serial port {device} is in use by {holder or 'another snakebot'}: stop "
                "that program first (two programs on one port read each other's replies)",
            ) from None
        holder = f"pid {os.getpid()} ({' '.join(Path(a).name for a in sys.argv[:3])})"
        os.ftruncate(self._fd, 0)  # a regular file of ours, locked: never someone else's
        os.pwrite(self._fd, holder.encode(), 0)

    def release(self) -> None:
        if self._fd >= 0:
            os.ftruncate(self._fd, 0)
            os.close(self._fd)  # closing the descriptor releases the flock
            self._fd = -1
