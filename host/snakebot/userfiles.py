"""Files the user names: read never beyond the largest valid one, written with the
permissions the user's umask gives.

A path to ``/dev/zero``, a disk image or a log file must not make snakebot read until
memory runs out: every reader of user files (gait tables, their metadata, robot files,
firmware images) goes through :func:`read_bounded` with the largest size its format
allows. Files written atomically (a temporary file, then a rename) start as 0600; they
get :func:`new_file_mode` so they end as any other file the user makes.
"""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from snakebot.errors import InputError


class FileTooLarge(InputError):
    """The file is larger than any valid file of its kind. ``size`` is its size in bytes
    when it has one (a regular file), else None (a device or pipe that goes on)."""

    def __init__(self, message: str, size: int | None) -> None:
        super().__init__(message)
        self.size = size


class NoSuchDirectory(InputError):
    """A file to write in a directory that is not there."""


def read_bounded(path: str | os.PathLike[str], limit: int, what: str) -> bytes:
    """The bytes of ``path`` if it holds at most ``limit`` of them, else
    :class:`FileTooLarge` naming ``what`` the file should be. Reads at most
    ``limit + 1`` bytes, so endless files (devices, pipes) end the read too. OSError as
    ``open`` raises it."""
    with open(path, "rb") as f:
        data = f.read(limit + 1)
        info = os.fstat(f.fileno())
    if len(data) > limit:
        size = info.st_size if stat.S_ISREG(info.st_mode) else None
        how_big = f"is {size} bytes, more than" if size is not None else "holds more than"
        raise FileTooLarge(
            f"{os.fspath(path)} {how_big} {limit} bytes, the largest {what} there can be: "
            "check that it is the right file",
            size,
        )
    return data


def new_file_mode() -> int:
    """The mode ``open()`` gives a new file: 0666 less the process's umask."""
    mask = os.umask(0o022)  # the only way to read it is to set it; put it back at once
    os.umask(mask)
    return 0o666 & ~mask


@contextmanager
def staged_path(target: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path beside ``target`` for a writer that wants a file name (a video
    encoder, an MCAP writer); moved over ``target`` when the block ends without an
    exception, removed otherwise. It keeps ``target``'s suffix, which encoders read."""
    target = Path(target)
    if not target.parent.is_dir():
        raise NoSuchDirectory(
            f"{target}: the directory {target.parent} does not exist: create it, or name a "
            "file in a directory that does"
        )
    fd, name = tempfile.mkstemp(
        dir=target.parent, prefix=f".{target.stem}.", suffix=f".tmp{target.suffix}"
    )
    os.close(fd)
    temp = Path(name)
    try:
        yield temp
        os.chmod(temp, new_file_mode())
        os.replace(temp, target)
    finally:
        temp.unlink(missing_ok=True)


def write_file_atomically(target: str | os.PathLike[str], data: str | bytes) -> Path:
    """Replace ``target`` by ``data`` (text is UTF-8) in one step: a reader sees the old
    file or the whole new one."""
    with staged_path(target) as temp:
        temp.write_bytes(data.encode() if isinstance(data, str) else data)
    return Path(target)
