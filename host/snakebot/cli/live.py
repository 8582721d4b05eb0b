"""``--foxglove [HOST:]PORT``: the Foxglove WebSocket server a command starts beside its
work (``snakebot.workflows.foxglove``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import click

F = TypeVar("F", bound=Callable[..., Any])

RATE_HZ = 50.0
"""How often a command sends the robot's state to Foxglove."""


class EndpointType(click.ParamType):
    name = "[HOST:]PORT"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        from snakebot.workflows.foxglove import FoxgloveOptionError, parse_endpoint

        if isinstance(value, tuple):
            return value
        try:
            return parse_endpoint(str(value))
        except FoxgloveOptionError as exc:
            self.fail(str(exc), param, ctx)


def foxglove_option(func: F) -> F:
    """``--foxglove [HOST:]PORT`` as the parameter ``foxglove`` ((host, port) or None)."""
    return click.option(
        "--foxglove",
        type=EndpointType(),
        help="Stream the robot live to Foxglove (open ws://HOST:PORT in Foxglove): "
        "/joint_states, /tf, /robot_description and the servos' goals, loads and errors, "
        f"{RATE_HZ:g} times a second. Listens on 127.0.0.1 unless a HOST is given "
        "(0.0.0.0: every interface); PORT 0 takes a free one.",
    )(func)
