"""The ``--video FILE`` and ``--size WxH`` options of the commands that film a run
(``sim predict``, ``sim thesis``, ``sim goto``, ``demo``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import click

from snakebot.cli.params import OutputPathType
from snakebot.plots.video import DEFAULT_SIZE, SUFFIXES, VideoError, parse_size

F = TypeVar("F", bound=Callable[..., Any])

VIDEO_WORDS = (
    "in 3-D from MuJoCo's renderer (offscreen; the top view in 2-D where it cannot start), "
    "the camera following the body, its path on a 1 m grid, the time and the joint angles "
    "overlaid: .mp4 or .gif"
)


class SizeType(click.ParamType):
    name = "WxH"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, tuple):
            return value
        try:
            return parse_size(str(value))
        except VideoError as exc:
            self.fail(str(exc), param, ctx)


def video_options(what: str) -> Callable[[F], F]:
    """``--video`` (writing ``what``) and ``--size``, as the parameters ``video`` and
    ``video_size``."""

    def decorate(func: F) -> F:
        func = click.option(
            "--size",
            "video_size",
            type=SizeType(),
            default=f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}",
            show_default=True,
            help="The video's width x height in pixels (even numbers).",
        )(func)
        return click.option(
            "--video",
            type=OutputPathType(lambda: tuple(s.lstrip(".") for s in SUFFIXES)),
            help=f"Write a video of {what}: {VIDEO_WORDS}.",
        )(func)

    return decorate
