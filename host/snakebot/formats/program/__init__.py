"""Controller programs (protocol/program.md): a list of table, serpenoid and
periodic-input segments the controller runs on its own, built on the host, checked by
the controller's own C code. The programs in SI units that become these bytes are
:mod:`snakebot.model.program_spec`; the host's prediction of their goals is
:mod:`snakebot.model.program_goals`.

from snakebot.formats.program import Program
blob = program.encode()

May import: as the ``formats`` layer (``facts``, the other formats and the package root).
"""

from __future__ import annotations

from snakebot.formats.program.errors import ProgramError
from snakebot.formats.program.layout import (
    JointRecord,
    PeriodicSegment,
    Program,
    SerpenoidSegment,
    TableSegment,
    check,
    is_program,
)

__all__ = [
    "JointRecord",
    "PeriodicSegment",
    "Program",
    "ProgramError",
    "SerpenoidSegment",
    "TableSegment",
    "check",
    "is_program",
]
