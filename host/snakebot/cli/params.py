"""Click parameter types shared by the model and gait commands."""

from __future__ import annotations

from typing import Any

import click

from snakebot.gait.values import InputError, parse_angle, parse_angles


class AngleType(click.ParamType):
    """Radians (or rad/s), accepting ``pi`` expressions and a ``deg`` suffix."""

    name = "angle"

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> float:
        if isinstance(value, float):
            return value
        try:
            return parse_angle(str(value))
        except InputError as exc:
            self.fail(str(exc), param, ctx)


class AngleListType(click.ParamType):
    """A comma-separated list of angles."""

    name = "a,b,..."

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> list[float]:
        if isinstance(value, list):
            return value
        try:
            return parse_angles(str(value))
        except InputError as exc:
            self.fail(str(exc), param, ctx)


ANGLE = AngleType()
ANGLES = AngleListType()
