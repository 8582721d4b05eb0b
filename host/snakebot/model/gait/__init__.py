"""Gait generators: serpenoid (joint-space sines) and field-following (vector fields and
Lie brackets through periodic inputs). Each returns a ``Gait`` that becomes a gait table
(``Gait.gait_table()``) after passing the robot's joint-limit and speed checks.

The names below load with the module that defines them, when first used: a command that
only parses an angle (``values``) does not load the kinematics the generators need.

May import: as the ``model`` layer (the other ``model`` packages, ``formats``, ``facts``,
the package root)."""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
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

_HOMES = {
    "Gait": "common",
    "GaitError": "common",
    "GaitLimitError": "limits",
    "ExpressionError": "values",
    "check_motion": "limits",
    "check_ticks": "limits",
    "field_gait": "field",
    "parse_angle": "values",
    "parse_angles": "values",
    "parse_field_expression": "values",
    "SerpenoidWave": "serpenoid",
    "serpenoid": "serpenoid",
}
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


class _Package(types.ModuleType):
    """This package, keeping its names for what they name: once a submodule is loaded
    the import system sets it as the package's attribute of the same name, which for
    ``serpenoid`` (the module and its function) would turn the function into the module
    for every later ``from snakebot.model.gait import serpenoid``."""

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, types.ModuleType) and _HOMES.get(name) == name:
            value = getattr(value, name)
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{home}"), name)
    globals()[name] = value
    return value
