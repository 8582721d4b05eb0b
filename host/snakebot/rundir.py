"""Directories only this user can write: where snakebot keeps its port locks and the
records of the links its servers made.

``$XDG_RUNTIME_DIR`` (``/run/user/<uid>``, made by the login manager, 0700) when it is
set and safe; else ``<tmp>/snakebot-<uid>``, made 0700. A directory that is already
there is used only if it is a real directory (not a symbolic link), owned by this user
and writable by nobody else: in a shared ``/tmp`` another user can make the directory
first (the uid in its name is predictable), fill it with symbolic links to this user's
files and wait. Such a directory is refused with a message that names it, its owner and
the fix; it is never repaired, since a directory someone else owns cannot be.
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

from snakebot.errors import InputError

RUNTIME_ENV = "XDG_RUNTIME_DIR"
"""The freedesktop.org base directory for a user's runtime files (not a SNAKEBOT_*
setting: the login manager sets it)."""


class UnsafeDirectory(InputError):
    """A directory snakebot would keep private files in is not private. ``path`` is it."""

    def __init__(self, path: Path, message: str) -> None:
        super().__init__(message)
        self.path = path


def _problem(info: os.stat_result) -> str | None:
    """Why a directory with this ``lstat`` is not private, or None."""
    if stat.S_ISLNK(info.st_mode):
        return "is a symbolic link"
    if not stat.S_ISDIR(info.st_mode):
        return "is not a directory"
    if info.st_uid != os.geteuid():
        return f"belongs to uid {info.st_uid}, not to you (uid {os.geteuid()})"
    if info.st_mode & 0o022:
        return f"can be written by others (mode {stat.S_IMODE(info.st_mode):04o})"
    return None


def _owner_name(uid: int) -> str:
    try:
        import pwd

        return f"{pwd.getpwuid(uid).pw_name} (uid {uid})"
    except (ImportError, KeyError):
        return f"uid {uid}"


def ensure_private(path: Path) -> Path:
    """``path``, made 0700 if missing; :class:`UnsafeDirectory` if it is there and not
    private (see the module docstring)."""
    try:
        os.mkdir(path, 0o700)
    except FileExistsError:
        pass
    except OSError as exc:
        raise UnsafeDirectory(
            path, f"cannot make the directory {path}: {exc.strerror or exc}: check its parent"
        ) from exc
    info = os.lstat(path)
    problem = _problem(info)
    if problem is not None:
        owner = _owner_name(info.st_uid)
        raise UnsafeDirectory(
            path,
            f"{path} {problem} (owner {owner}): someone else may have planted it to make "
            f"snakebot write through it, so it is not used; remove it (rm -r {path}, as its "
            f"owner or root) or set {RUNTIME_ENV} to a directory only you can write",
        )
    return path


def _runtime_base() -> Path | None:
    value = os.environ.get(RUNTIME_ENV, "")
    if not value or not os.path.isabs(value):
        return None
    try:
        info = os.lstat(value)
    except OSError:
        return None
    return Path(value) if _problem(info) is None else None


def private_dir(name: str) -> Path:
    """``$XDG_RUNTIME_DIR/<name>``, or ``<tmp>/<name>-<uid>`` when that variable is unset
    or not a private directory of this user; made and checked by :func:`ensure_private`."""
    base = _runtime_base()
    if base is not None:
        return ensure_private(base / name)
    return ensure_private(Path(tempfile.gettempdir()) / f"{name}-{os.geteuid()}")
