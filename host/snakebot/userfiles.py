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

from snakebot.errors import InputError


class FileTooLarge(InputError):
    """The file is larger than any valid file of its kind. ``size`` is its size in bytes
    when it has one (a regular file), else None (a device or pipe that goes on)."""

    def __init__(self, message: str, size: int | None) -> None:
        super().__init__(message)
        self.size = size


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
