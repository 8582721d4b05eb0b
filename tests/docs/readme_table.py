"""The README's "What you can do" table as commands to run: a Sybil parser for its rows
and what each command's inline code stands for.

A row's second column shows commands as inline code. A span that starts with
``snakebot`` or ``make`` is a command; any other span (```ping```, ```--json```,
```limits show```) names a part of one in the prose and is counted, not run. A command
stands for several lines: without its bracketed optional parts, then with each of them
(``[a | b]`` once with ``a`` and once with ``b``), except a bracket that names a file
the reader chooses (``[FILE.bin/.hex/.elf]``, upper case); ``...`` as a port is the
reader's port, replaced by an emulator's as the fenced blocks' ``/dev/ttyUSB0`` is
(tests/docs/runnable.py).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass

from sybil import Document, Region

HEADER = re.compile(r"^\| task \| command \|\n\|---\|---\|\n", re.M)
CELL = re.compile(r"(?<!\\)\|")
CODE = re.compile(r"`([^`]+)`")
OPTIONAL = re.compile(r" ?\[([^\]]+)\]")
PLACEHOLDER = re.compile(r"\b[A-Z]{2,}\b")  # FILE, PORT: a name the reader fills in
COMMAND = re.compile(r"^(?:snakebot|make) ")
READER_PORT = "/dev/ttyUSB0"


@dataclass(frozen=True)
class Row:
    """One row of the table: its task, and the inline code of its command column."""

    task: str
    spans: tuple[str, ...]

    @property
    def commands(self) -> list[str]:
        return [s for s in self.spans if COMMAND.match(s)]

    @property
    def mentions(self) -> list[str]:
        """Inline code that names a part of a command (not run)."""
        return [s for s in self.spans if not COMMAND.match(s)]


def variants(command: str) -> list[str]:
    """The lines a command with optional parts stands for: none of them, then each one
    alone (each alternative of ``[a | b]``), ``...`` ports as the reader's port."""
    brackets = list(OPTIONAL.finditer(command))

    def line(keep: re.Match[str] | None = None, choice: str = "") -> str:
        text, end = "", 0
        for m in brackets:
            text += command[end : m.start()] + (f" {choice}" if m is keep else "")
            end = m.end()
        text += command[end:]
        return " ".join(READER_PORT if w == "..." else w for w in text.split())

    found = [line()]
    for m in brackets:
        for choice in (c.strip() for c in m.group(1).split("|")):
            if not PLACEHOLDER.search(choice):
                found.append(line(m, choice))
    return found


def parse_rows(document: Document) -> Iterator[Region]:
    """Sybil parser: a region for each row of a ``| task | command |`` table, parsed as a
    :class:`Row`."""
    for header in HEADER.finditer(document.text):
        position = header.end()
        for text in document.text[position:].split("\n"):
            if not text.startswith("|"):
                break
            cells = [c.strip() for c in CELL.split(text)[1:-1]]
            spans = tuple(s.replace("\\|", "|") for s in CODE.findall(cells[1]))
            yield Region(position, position + len(text), Row(cells[0], spans))
            position += len(text) + 1
