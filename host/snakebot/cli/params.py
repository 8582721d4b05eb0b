"""Click parameter types shared by the commands: angles, lists of angles, and finite
numbers in a range. Every number on the command line goes through one of them, so NaN,
infinities and absurd magnitudes are refused while parsing, before anything is opened."""

from __future__ import annotations

import math
import os
import stat
from collections.abc import Callable, Collection
from pathlib import Path
from typing import Any, TypeVar

import click

from snakebot.model.gait.values import ExpressionError, parse_angle, parse_angles


def _parsed(
    parse: Callable[[str], T],
    text: str,
    limit: int,
    kind: click.ParamType,
    param: click.Parameter | None,
    ctx: click.Context | None,
) -> T:
    """``parse(text)``, with every way it can fail turned into a usage error. The length
    limit keeps the parser's time and recursion bounded (5,000 unary minus signs)."""
    if len(text) > limit:
        kind.fail(
            f"{_shown(text)} is too long for a value ({limit} characters at most)", param, ctx
        )
    try:
        return parse(text)
    except ExpressionError as exc:
        kind.fail(str(exc), param, ctx)
    except (OverflowError, RecursionError, MemoryError, ValueError):
        kind.fail(f"{_shown(text)} is not a finite number", param, ctx)


MAX_NUMBER_CHARS = 64
"""Longer text is not a number anyone means (a 400-digit value overflows to infinity)."""

MAX_LIST_CHARS = 1024
"""The longest comma-separated list of values taken."""

T = TypeVar("T")


class AngleType(click.ParamType):
    """Radians (or rad/s), accepting ``pi`` expressions and a ``deg`` suffix."""

    name = "angle"

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> float:
        if isinstance(value, float):
            return value
        return _parsed(parse_angle, str(value), MAX_NUMBER_CHARS, self, param, ctx)


class AngleListType(click.ParamType):
    """A comma-separated list of angles."""

    name = "a,b,..."

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> list[float]:
        if isinstance(value, list):
            return value
        return _parsed(parse_angles, str(value), MAX_LIST_CHARS, self, param, ctx)


ANGLE = AngleType()
ANGLES = AngleListType()

F = TypeVar("F", bound=Callable[..., Any])


def wave_options(func: F) -> F:
    """--amplitude, --omega and --delta of a serpenoid with the demo's wave as defaults,
    for the commands that run one without a gait file (`demo`, `drive`)."""
    for option in reversed(
        (
            click.option(
                "--amplitude",
                "-A",
                type=ANGLE,
                default="30deg",
                show_default=True,
                help="Serpenoid amplitude A (rad, or deg with 'deg').",
            ),
            click.option(
                "--omega",
                "-w",
                type=ANGLE,
                default="180deg",
                show_default=True,
                help="Serpenoid temporal frequency omega (rad/s, or deg/s with 'deg').",
            ),
            click.option(
                "--delta",
                "-d",
                type=ANGLE,
                default="90deg",
                show_default=True,
                help="Serpenoid phase step from one joint to the next (rad or deg).",
            ),
        )
    ):
        func = option(func)
    return func


class NumberType(click.ParamType):
    """A finite real number, optionally within ``low``..``high`` (open ends with
    ``low_open``/``high_open``). NaN, infinities and out-of-range values are refused as
    usage errors (exit 2) that say what is allowed."""

    name = "number"

    def __init__(
        self,
        low: float | None = None,
        high: float | None = None,
        *,
        low_open: bool = False,
        high_open: bool = False,
    ) -> None:
        self.low, self.high = low, high
        self.low_open, self.high_open = low_open, high_open

    def _allowed(self) -> str:
        parts = []
        if self.low is not None:
            parts.append(f"{'>' if self.low_open else '>='} {self.low:g}")
        if self.high is not None:
            parts.append(f"{'<' if self.high_open else '<='} {self.high:g}")
        return "a finite number" + (" " + " and ".join(parts) if parts else "")

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> float:
        if isinstance(value, float) and math.isfinite(value):
            number = value
        else:
            text = str(value).strip()
            try:
                number = float(text) if len(text) <= MAX_NUMBER_CHARS else math.nan
            except ValueError:
                number = math.nan
            if not math.isfinite(number):
                self.fail(f"{_shown(text)} is not {self._allowed()}", param, ctx)
        low_bad = self.low is not None and (
            number < self.low or (self.low_open and number == self.low)
        )
        high_bad = self.high is not None and (
            number > self.high or (self.high_open and number == self.high)
        )
        if low_bad or high_bad:
            self.fail(f"{number:g} is not {self._allowed()}", param, ctx)
        return number

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        return "NUMBER"


def _shown(text: str) -> str:
    return repr(text if len(text) <= 40 else text[:37] + "...")


NUMBER = NumberType()


class OutputPathType(click.Path):
    """A file to write: not empty, not a directory; with ``suffixes``, one of those
    extensions (case-insensitive), so a format nobody can write is refused before any
    work is done."""

    def __init__(self, suffixes: Callable[[], Collection[str]] | None = None) -> None:
        super().__init__(dir_okay=False, path_type=Path)
        self.suffixes = suffixes

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if not str(value).strip():
            self.fail("an empty path: name the file to write", param, ctx)
        path = super().convert(value, param, ctx)
        if os.path.exists(path) and not stat.S_ISREG(os.stat(path).st_mode):
            # Files are written beside the target and moved over it: that would put a
            # regular file in place of a device or a pipe.
            self.fail(
                f"{str(path)!r} is a device or a pipe, not a file: name a file to write",
                param,
                ctx,
            )
        if self.suffixes is not None:
            known = self.suffixes()
            suffix = Path(path).suffix.lower().lstrip(".")
            if suffix not in known:
                self.fail(
                    f"{str(path)!r} has the extension {suffix or '(none)'!r}: use one of "
                    + ", ".join(f".{s}" for s in sorted(known)),
                    param,
                    ctx,
                )
        return path


def _plot_formats() -> Collection[str]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # only when a plot is asked

    return FigureCanvasAgg.get_supported_filetypes().keys()


OUTPUT_PATH = OutputPathType()
PLOT_PATH = OutputPathType(_plot_formats)


SERVO_BUS_SCHEME = "sim://"


def controller_port(server: str) -> Callable[[click.Context, click.Parameter, Any], Any]:
    """A --port callback for commands that talk to the controller (or its bootloader): a
    sim:// URL is an emulated servo bus with no controller on it, so it is refused with
    the command that emulates one (``server``)."""

    def check(ctx: click.Context, param: click.Parameter, value: Any) -> Any:
        if isinstance(value, str) and value.startswith(SERVO_BUS_SCHEME):
            raise click.BadParameter(
                f"{value} is an emulated servo bus, with no controller on it: run "
                f"`{server}` and give the pseudo-terminal it prints as --port",
                ctx,
                param,
            )
        return value

    return check


class LazyChoice(click.Choice):
    """A choice whose list lives in a module the CLI should not import at start-up: it is
    read from ``module.attribute`` the first time the choices are needed (parsing the
    option, or its help)."""

    def __init__(self, module: str, attribute: str) -> None:
        self._source = (module, attribute)
        self._choices: tuple[str, ...] | None = None
        self.case_sensitive = True

    @property
    def choices(self) -> tuple[str, ...]:  # type: ignore[override]
        if self._choices is None:
            import importlib

            module, attribute = self._source
            self._choices = tuple(getattr(importlib.import_module(module), attribute))
        return self._choices

    @choices.setter
    def choices(self, value: Any) -> None:
        self._choices = tuple(value)
