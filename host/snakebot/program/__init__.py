"""Controller programs (protocol/program.md): a list of table, serpenoid and
periodic-input segments the controller runs on its own, built on the host, checked by
the controller's own C code, and predicted step by step.

from snakebot.program import Program, predict
blob = program.encode(); goals = predict(program)
"""

from __future__ import annotations

from snakebot.program.errors import ProgramError
from snakebot.program.layout import (
    JointRecord,
    PeriodicSegment,
    Program,
    SerpenoidSegment,
    TableSegment,
    check,
    is_program,
)
from snakebot.program.predict import predict, predicted_ticks

__all__ = [
    "JointRecord",
    "PeriodicSegment",
    "Program",
    "ProgramError",
    "SerpenoidSegment",
    "TableSegment",
    "check",
    "is_program",
    "predict",
    "predicted_ticks",
]
