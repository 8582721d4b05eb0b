"""Gait generators: serpenoid (joint-space sines) and field-following (vector fields and
Lie brackets through periodic inputs). Each returns a ``Gait`` that becomes a gait table
(``Gait.gait_table()``) after passing the robot's joint-limit and speed checks.

May import: as the ``model`` layer (the other ``model`` packages, ``formats``, ``facts``,
the package root)."""

from __future__ import annotations

from snakebot.model.gait.common import Gait, GaitError
from snakebot.model.gait.field import field_gait
from snakebot.model.gait.limits import GaitLimitError, check_motion, check_ticks
from snakebot.model.gait.serpenoid import SerpenoidWave, serpenoid
from snakebot.model.gait.values import (
    ExpressionError,
    parse_angle,
    parse_angles,
    parse_field_expression,
)

__all__ = [
    "Gait",
    "GaitError",
    "GaitLimitError",
    "ExpressionError",
    "SerpenoidWave",
    "check_motion",
    "check_ticks",
    "field_gait",
    "parse_angle",
    "parse_angles",
    "parse_field_expression",
    "serpenoid",
]
