"""Files the user names: read never beyond the largest valid one, written in one step,
never through a symbolic link and never onto a device.

Reading, the one way for every input (:func:`read_bounded`, :func:`read_text_bounded`,
:func:`open_input`): a path to ``/dev/zero``, a FIFO nobody writes, a disk image or a log
file must neither hang snakebot nor make it read until memory runs out. The file is
opened without blocking and read only if it is a regular file, and never beyond the
largest valid file of its kind (gait tables, their metadata, programs, robot files,
firmware images, library backups, recordings, emulator state files); text that is not
UTF-8 is refused with the offset of the first bad byte.

Writing, the one way for every output (:func:`check_output`, :func:`atomic_output`,
:func:`staged_output`, :func:`write_atomic`, :func:`open_recording`):

* checked first, so that a refusal comes before the work: a directory, a device, a FIFO
  or a socket is refused (a rename would put a regular file in place of a device node),
  and so is a symbolic link at the final path (see :func:`output_problem` for why it is
  refused rather than replaced), and a directory that does not exist;
* atomic: a temporary file in the same directory, written, ``fsync``-ed, then renamed
  over the target, so a reader sees the old file or the new one and an error or a kill
  leaves no half-written file; the rename replaces whatever name is there and never
  writes through a link planted after the check;
* with the mode of the file it replaces, else what ``open()`` would give a new file
  (0666 less the umask), not the 0600 of a temporary file;
* recordings that must survive a kill (``monitor --csv/--mcap``) are the exception to
  atomicity: :func:`open_recording` opens the final path itself, with ``O_NOFOLLOW``, and
  truncates it only once it is known to be a regular file.
"""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from snakebot.errors import InputError, quoted

PathLike = str | os.PathLike[str]


class UnreadableInput(InputError):
    """An input file snakebot will not read: too large, not a regular file, or not the
    text it should be (bad input, exit 2)."""


class FileTooLarge(UnreadableInput):
    """The file is larger than any valid file of its kind. ``size`` is its size in bytes
    when it has one (a regular file), else None (a device or pipe that goes on)."""

    def __init__(self, message: str, size: int | None) -> None:
        super().__init__(message)
        self.size = size


class NotAFile(UnreadableInput):
    """The path is a FIFO, a device, a socket or a directory: something that may never
    end or never answer, so it is not read at all."""


class NotText(UnreadableInput):
    """The file is not UTF-8 text."""


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (a named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "a socket or other special file"


def open_input(path: PathLike, what: str) -> int:
    """A descriptor of ``path`` opened for reading without blocking (a FIFO with no
    writer does not hang the open) and known to be a regular file; :class:`NotAFile`
    naming what it is otherwise, OSError as ``open`` raises it."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        raise NotAFile(
            f"{os.fspath(path)} is {_kind(info.st_mode)}, not a file: give the {what} "
            "as a regular file"
        )
    os.set_blocking(fd, True)
    return fd


def read_bounded(path: PathLike, limit: int, what: str) -> bytes:
    """The bytes of ``path`` if it is a regular file (:func:`open_input`) holding at
    most ``limit`` of them, else :class:`NotAFile` or :class:`FileTooLarge` naming
    ``what`` the file should be. Reads at most ``limit + 1`` bytes, so a file that grows
    while it is read ends the read too. OSError as ``open`` raises it."""
    with open(open_input(path, what), "rb") as f:
        data = f.read(limit + 1)
        info = os.fstat(f.fileno())
    if len(data) > limit:
        raise FileTooLarge(
            f"{os.fspath(path)} is {info.st_size} bytes, more than {limit} bytes, the "
            f"largest {what} there can be: check that it is the right file",
            info.st_size,
        )
    return data


def read_text_bounded(path: PathLike, limit: int, what: str) -> str:
    """:func:`read_bounded`, decoded as UTF-8; :class:`NotText` naming the first bad
    byte and its offset if it is not UTF-8."""
    data = read_bounded(path, limit, what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise NotText(
            f"{os.fspath(path)} is not UTF-8 text (byte 0x{data[exc.start]:02x} at offset "
            f"{exc.start}): is it a {what}?"
        ) from None


def new_file_mode() -> int:
    """The mode ``open()`` gives a new file: 0666 less the process's umask."""
    mask = os.umask(0o022)  # the only way to read it is to set it; put it back at once
    os.umask(mask)
    return 0o666 & ~mask


class OutputRefused(InputError):
    """A path given for an output cannot be written safely (bad input, exit 2)."""


def output_problem(path: PathLike) -> str | None:
    """Why ``path`` cannot be an output (the end of a sentence that starts with the
    path), or None if it can.

    A symbolic link at the path is refused, not replaced. Writing through it would
    overwrite its target, which in a shared directory (``/tmp``) may be another user's
    file planted there for that purpose; replacing it would silently turn a link the user
    made on purpose into a file and leave the file they meant unchanged. Refusing says
    so, and the fix (name the file itself) is one word away."""
    path = os.fspath(path)
    if not path.strip():
        return "is empty: name the file to write"
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        parent = os.path.dirname(path) or "."
        if not os.path.isdir(parent):
            return f"is in {parent}, which is not a directory: make it first (mkdir -p {parent})"
        return None
    except OSError as exc:
        return f"cannot be looked at ({exc.strerror or exc}): check the path"
    if stat.S_ISLNK(info.st_mode):
        target = os.readlink(path)
        return (
            f"is a symbolic link (to {target}): snakebot never writes through a link nor "
            "replaces one, since a link planted by someone else would make it overwrite "
            "their choice of file; name the file itself, or remove the link"
        )
    if stat.S_ISDIR(info.st_mode):
        return "is a directory: name a file to write"
    if not stat.S_ISREG(info.st_mode):
        return "is a device, a pipe or a socket, not a file: name a regular file to write"
    return None


def check_output(path: PathLike) -> Path:
    """``path`` as a Path if it can be an output, else :class:`OutputRefused` naming
    the problem and the fix (see :func:`output_problem`)."""
    problem = output_problem(path)
    if problem is not None:
        raise OutputRefused(f"{quoted(os.fspath(path))} {problem}")
    return Path(path)


def same_file(a: PathLike, b: PathLike) -> bool:
    """Whether two output paths name one file (by their real paths, or the same inode
    when both exist)."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _final_mode(path: Path) -> int:
    try:
        info = os.lstat(path)
    except OSError:
        return new_file_mode()
    return stat.S_IMODE(info.st_mode) if stat.S_ISREG(info.st_mode) else new_file_mode()


class OutputExists(OutputRefused):
    """An output that must be new names a file that exists (bad input, exit 2)."""

    def __init__(self, target: PathLike) -> None:
        super().__init__(
            f"{quoted(os.fspath(target))} exists already: name a new file, or allow replacing it"
        )


def _finish(temp: Path, target: Path, mode: int, replace: bool = True) -> None:
    fd = os.open(temp, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    try:
        os.fchmod(fd, mode)
        os.fsync(fd)
    finally:
        os.close(fd)
    if replace:
        os.replace(temp, target)  # replaces the name: never writes through what is there
        return
    try:
        os.link(temp, target)  # a new name only: fails, in one step, if there is one
    except FileExistsError:
        raise OutputExists(target) from None


@contextmanager
def staged_output(path: PathLike, *, replace: bool = True) -> Iterator[Path]:
    """A temporary path beside ``path``, with the same suffix (for writers that pick the
    format by name: matplotlib, Pillow, ffmpeg, pyarrow), moved over ``path`` when the
    block ends without an exception and removed when it raises. ``path`` is checked
    first (:func:`check_output`). With ``replace`` false a file already at ``path`` is
    kept and :class:`OutputExists` raised (checked before and, atomically, at the end)."""
    target = check_output(path)
    if not replace and os.path.lexists(target):
        raise OutputExists(target)
    mode = _final_mode(target)
    fd, name = tempfile.mkstemp(
        dir=target.parent, prefix=f".{target.stem}.", suffix=f".tmp{target.suffix}"
    )
    os.close(fd)
    temp = Path(name)
    try:
        yield temp
        _finish(temp, target, mode, replace)
    finally:
        temp.unlink(missing_ok=True)


@contextmanager
def atomic_output(path: PathLike, *, text: bool = False, replace: bool = True) -> Iterator[IO[Any]]:
    """A file object whose content replaces ``path`` in one step when the block ends
    without an exception (:func:`staged_output`); ``text`` opens it for ``str`` with
    ``newline=""`` (as ``csv`` wants); ``replace`` as for :func:`staged_output`."""
    with staged_output(path, replace=replace) as temp:
        if text:
            with open(temp, "w", newline="", encoding="utf-8") as f:
                yield f
        else:
            with open(temp, "wb") as f:
                yield f


def write_atomic(path: PathLike, data: bytes | str, *, replace: bool = True) -> Path:
    """Replace ``path`` by ``data`` in one step (:func:`atomic_output`); with ``replace``
    false, write a new file and refuse an existing one (:class:`OutputExists`)."""
    with atomic_output(path, text=isinstance(data, str), replace=replace) as f:
        f.write(data)
    return Path(path)


def open_recording(path: PathLike, *, text: bool = False) -> IO[Any]:
    """``path`` opened for a recording that must survive a kill: the final file itself,
    emptied and written as the recording goes, not a temporary file. Opened with
    ``O_NOFOLLOW`` and ``O_NONBLOCK`` (a FIFO with no reader does not block) and
    emptied only once it is known to be a regular file: :class:`OutputRefused`
    otherwise, OSError as ``open`` raises it."""
    target = check_output(path)
    flags = os.O_WRONLY | os.O_CREAT | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(target, flags | getattr(os, "O_CLOEXEC", 0), 0o666)
    except OSError:
        problem = output_problem(target)  # planted between the check and the open
        if problem is not None:
            raise OutputRefused(f"{quoted(os.fspath(path))} {problem}") from None
        raise
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise OutputRefused(
            f"{quoted(os.fspath(path))} {output_problem(target) or 'is not a file'}"
        )
    os.set_blocking(fd, True)
    os.ftruncate(fd, 0)
    if text:
        return open(fd, "w", newline="", encoding="utf-8", buffering=1)
    return open(fd, "wb")
