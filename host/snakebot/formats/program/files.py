"""Program files (``.prog``): the blob's exact bytes, read with a size bound and checked
by the controller's own code before anything else sees them."""

from __future__ import annotations

import os
from pathlib import Path

from snakebot.formats.program.errors import ProgramError
from snakebot.formats.program.layout import CAPACITY, MAGIC, Program
from snakebot.userfiles import UnreadableInput, read_bounded, write_atomic


def read_program(path: str | os.PathLike[str]) -> Program:
    """The program in ``path``; ProgramError naming the problem (missing file, too big,
    or what the controller would refuse it for)."""
    try:
        data = read_bounded(path, CAPACITY, "program")
    except UnreadableInput as exc:
        raise ProgramError(str(exc)) from exc
    except OSError as exc:
        raise ProgramError(
            f"cannot read program {os.fspath(path)}: {exc.strerror or exc}; check the path "
            "(programs are written by `snakebot program build`)"
        ) from exc
    try:
        return Program.decode(data)
    except ProgramError as exc:
        raise ProgramError(f"{os.fspath(path)}: {exc}", exc.code) from exc


def write_program(path: str | os.PathLike[str], program: Program) -> None:
    """Write the program's bytes to ``path`` (through a temporary file, so a failed write
    leaves no half-written program)."""
    target = Path(path)
    data = program.encode()
    try:
        write_atomic(target, data)
    except OSError as exc:
        raise ProgramError(
            f"cannot write {target}: {exc.strerror or exc}; choose a writable path"
        ) from exc


def is_program_file(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` starts like a program (else it is taken for a gait table)."""
    try:
        with open(path, "rb") as f:
            return f.read(len(MAGIC)) == MAGIC
    except OSError:
        return False
