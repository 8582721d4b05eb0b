"""Click parameter types shared by the commands: angles, lists of angles, finite numbers
in a range, files to write, poses (X,Y,THETA), table capacities and robots. Every number on the
command line goes through one of them, so NaN, infinities and absurd magnitudes are
refused while parsing, before anything is opened. The options built on them, each
declared once, are in ``options``."""

from __future__ import annotations

import functools
import math
import os
import re
import stat
from collections.abc import Callable, Collection
from pathlib import Path
from typing import Any, TypeVar

import click

from snakebot.errors import InputError, quoted
from snakebot.extras import require
from snakebot.facts.boards import TABLE_CAPACITY
from snakebot.model.gait.limits import GaitLimitError
from snakebot.model.gait.values import ExpressionError, parse_angle, parse_angles, parse_number


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
F = TypeVar("F", bound=Callable[..., Any])


BARE_ANGLES = "snakebot.bare_angles"
"""Where :class:`AngleType` notes the options given as a bare number (``ctx.meta``)."""

_BARE_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)")


class AngleType(click.ParamType):
    """Radians (or rad/s), accepting ``pi`` expressions and a ``deg`` suffix. A bare
    number is radians; it is noted so a limit error can say so (:func:`bare_angle_hint`)."""

    name = "angle"

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> float:
        if isinstance(value, float):
            return value
        text = str(value).strip()
        angle = _parsed(parse_angle, text, MAX_NUMBER_CHARS, self, param, ctx)
        if ctx is not None and param is not None and angle and _BARE_NUMBER.fullmatch(text):
            name = param.opts[-1] if len(param.opts[-1]) == 2 else param.opts[0]
            ctx.meta.setdefault(BARE_ANGLES, []).append(f"{name} {text}")
        return angle


def bare_angle_hint(func: F) -> F:
    """A command whose limit check fails while some angle was given without a unit: the
    error also says that a bare number is radians, and how to write degrees."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except GaitLimitError as exc:
            bare = click.get_current_context().meta.get(BARE_ANGLES)
            if bare:
                first = bare[0]
                exc.args = (
                    f"{exc}. Note: {', '.join(bare)} {'is' if len(bare) == 1 else 'are'} in "
                    f"radians (rad/s for a speed): a number without a unit is radians; for "
                    f"degrees write {first}deg",
                )
            raise

    return wrapper  # type: ignore[return-value]


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
    """A file to write, checked while parsing (``snakebot.userfiles.output_problem``): not
    empty, not a directory, device, FIFO or socket, not a symbolic link, in a directory
    that exists; not a file another output option of the same command names; with
    ``suffixes``, one of those extensions (case-insensitive). So a refusal comes before
    any work is done, never after a long search."""

    def __init__(self, suffixes: Callable[[], Collection[str]] | None = None) -> None:
        super().__init__(dir_okay=False, path_type=Path)
        self.suffixes = suffixes

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, Path) and ctx is not None and value in _outputs(ctx).values():
            return value  # converted already (click converts a default twice)
        from snakebot.userfiles import output_problem, same_file  # when an output is given

        problem = output_problem(str(value))
        if problem is not None:
            self.fail(f"{quoted(str(value))} {problem}", param, ctx)
        path = Path(value)
        if self.suffixes is not None:
            known = self.suffixes()
            suffix = path.suffix.lower().lstrip(".")
            if suffix not in known:
                self.fail(
                    f"{quoted(str(path))} has the extension {suffix or '(none)'!r}: use one of "
                    + ", ".join(f".{s}" for s in sorted(known)),
                    param,
                    ctx,
                )
        if ctx is not None:
            name = param.get_error_hint(ctx) if param is not None else "an output"
            outputs = _outputs(ctx)
            for other_name, other in outputs.items():
                if other_name != name and same_file(other, path):
                    self.fail(
                        f"{quoted(str(path))} is also given to {other_name}: two outputs would "
                        "overwrite each other; give each its own file",
                        param,
                        ctx,
                    )
            outputs[name] = path
        return path


class InputPathType(click.Path):
    """A file to read, checked while parsing: if it is there it must be a regular file
    (or a link to one), never a FIFO, device, socket or directory, which could block the
    read or never end. A missing file is left to the reader, whose message says how to
    make one (``exists`` makes click refuse it here)."""

    def __init__(self, exists: bool = False, path_type: type[Any] = Path) -> None:
        super().__init__(exists=exists, dir_okay=False, path_type=path_type)

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if not str(value).strip():
            self.fail("an empty path: name the file to read", param, ctx)
        path = super().convert(value, param, ctx)
        try:
            mode = os.stat(path).st_mode
        except OSError:
            return path  # missing or unreadable: the reader says what to do
        if not stat.S_ISREG(mode):
            self.fail(
                f"{quoted(str(path))} is a FIFO, a device or a socket, not a file: give a "
                "regular file",
                param,
                ctx,
            )
        return path


INPUT_PATH = InputPathType()
EXISTING_INPUT = InputPathType(exists=True)
INPUT_TEXT_PATH = InputPathType(path_type=str)
"""An input whose path the command keeps as text (to print it back)."""


def _outputs(ctx: click.Context) -> dict[str, Path]:
    """The outputs of this command line so far (option hint -> path), shared by its
    contexts."""
    return ctx.find_root().meta.setdefault("snakebot.outputs", {})


def _plot_formats() -> Collection[str]:
    require("matplotlib", "a picture (--plot)")  # before any work, with the install to run
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # only when a plot is asked

    return FigureCanvasAgg.get_supported_filetypes().keys()


OUTPUT_PATH = OutputPathType()
PLOT_PATH = OutputPathType(_plot_formats)
PNG_PATH = OutputPathType(lambda: ("png",))
"""A picture that is always a PNG (the search's plot)."""


class PoseType(click.ParamType):
    """X,Y,THETA: two numbers in the robot's length units, and an angle (rad or deg)."""

    name = "x,y,theta"

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> tuple[float, float, float]:
        if isinstance(value, tuple):
            return value
        parts = str(value).split(",")
        if len(parts) != 3 or not all(p.strip() for p in parts):
            self.fail(
                f"{quoted(value)} is not X,Y,THETA: give three comma-separated values", param, ctx
            )
        try:
            return (parse_number(parts[0]), parse_number(parts[1]), parse_angle(parts[2]))
        except ExpressionError as exc:
            self.fail(str(exc), param, ctx)


POSE = PoseType()

#: The longest --capacity worth reading (a number of bytes or a board's name).
MAX_CAPACITY_CHARS = 32


class CapacityType(click.ParamType):
    """BYTES or a board's name: the table capacity a plan is made for, in bytes."""

    name = "capacity"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        if isinstance(value, int):
            return value
        text = str(value).strip().lower()
        if text in TABLE_CAPACITY:
            return TABLE_CAPACITY[text]
        if len(text) > MAX_CAPACITY_CHARS or not (text.isascii() and text.isdigit()):
            boards = ", ".join(sorted(TABLE_CAPACITY))
            shown = text if len(text) <= MAX_CAPACITY_CHARS else text[:MAX_CAPACITY_CHARS] + "..."
            self.fail(
                f"{quoted(shown)} is neither a whole number of bytes nor a board ({boards})",
                param,
                ctx,
            )
        return int(text)

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        return "BYTES|" + "|".join(sorted(TABLE_CAPACITY))


CAPACITY = CapacityType()


class RobotType(click.ParamType):
    """A built-in robot's name or a robot .toml file, loaded where it is given: a bad one
    is refused while parsing (exit 2) by every command, also by one that uses it only
    with another option (`bus play` and `monitor`: with --foxglove or --mcap). The
    command gets the text as given."""

    name = "robot"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
        from snakebot.model.robots import load_robot  # the robot loader: when first asked

        try:
            load_robot(value)
        except InputError as exc:
            self.fail(str(exc), param, ctx)
        return str(value)


ROBOT = RobotType()


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
