"""The search space: which serpenoid parameters vary and over what range, and which
robustness parameters (the floor's friction) each candidate is run over.

A parameter is written ``NAME=VALUE`` (fixed), ``NAME=LOW:HIGH`` (a range, for random
and cma searches) or ``NAME=LOW:HIGH:COUNT`` (COUNT evenly spaced values; what a grid
needs). Angles take the ``deg`` suffix and pi expressions of ``gait serpenoid``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from snakebot.errors import InputError, quoted
from snakebot.model.gait.values import ExpressionError, parse_angle, parse_number

GAIT_PARAMETERS = {
    "amplitude": ("amplitude", "A"),
    "omega": ("omega", "w"),
    "delta": ("delta", "d"),
    "offset": ("offset",),
}
"""The serpenoid's parameters (radians, rad/s) and the names they may be given by."""

ROBUST_PARAMETERS = {
    "mu": ("mu", "friction.lateral"),
    "mass": ("mass",),
    "rolling": ("rolling", "friction.rolling"),
}
"""What a candidate's robustness is tried over: the wheel-floor Coulomb coefficient
(``mu``) and the rolling resistance coefficient (``rolling``), in either world, and a
factor on every link's and wheel's mass (``mass``) in the physics world."""

ROBUST_WORLD = {
    "mu": ("kinematic", "mujoco"),
    "mass": ("mujoco",),
    "rolling": ("kinematic", "mujoco"),
}

REQUIRED = ("amplitude", "omega", "delta")
DEFAULTS = {"offset": 0.0}


MAX_RUNS = 100_000
"""The most runs one search makes (candidates times robustness values): 100,000 rows of
results and, in the kinematic world, a few minutes a core. A grid of 10^8 points took
5.4 GB before it ran anything."""


class SearchError(InputError):
    """A search that cannot run as asked; the message says what to change."""


@dataclass(frozen=True)
class Axis:
    """One parameter: ``low`` to ``high``; ``count`` evenly spaced values (None: a
    continuous range, 1: fixed at ``low``)."""

    name: str
    low: float
    high: float
    count: int | None

    @property
    def fixed(self) -> bool:
        return self.count == 1

    def values(self) -> np.ndarray:
        if self.count is None:
            raise SearchError(
                f"{self.name} is a range without a count: a grid needs "
                f"{self.name}=LOW:HIGH:COUNT (or search by the random or cma method)"
            ).about("params", "method")
        return np.linspace(self.low, self.high, self.count)

    def scale(self, unit: np.ndarray) -> np.ndarray:
        """Points of [0, 1] to the range."""
        return self.low + (self.high - self.low) * np.asarray(unit)


def _canonical(name: str, table: dict[str, tuple[str, ...]], what: str) -> str:
    for canonical, aliases in table.items():
        if name in aliases:
            return canonical
    known = ", ".join(a for aliases in table.values() for a in aliases)
    raise SearchError(f"unknown {what} {quoted(name)}: use one of {known}")


def parse_axis(text: str, robust: bool = False) -> Axis:
    """``NAME=VALUE``, ``NAME=LOW:HIGH`` or ``NAME=LOW:HIGH:COUNT`` as an Axis."""
    param = "robust" if robust else "params"
    name, sep, spec = text.partition("=")
    if not sep or not name.strip() or not spec.strip():
        raise SearchError(
            f"{quoted(text)}: write NAME=VALUE, NAME=LOW:HIGH or NAME=LOW:HIGH:COUNT"
        ).about(param)
    table = ROBUST_PARAMETERS if robust else GAIT_PARAMETERS
    canonical = _canonical(name.strip(), table, "robustness parameter" if robust else "parameter")
    parse = parse_number if robust else parse_angle
    parts = spec.split(":")
    if len(parts) > 3:
        raise SearchError(f"{quoted(text)}: at most LOW:HIGH:COUNT").about(param)
    try:
        numbers = [parse(p.strip()) for p in parts[:2]]
        count = None if len(parts) < 3 else int(parts[2].strip())
    except ExpressionError as exc:
        raise SearchError(f"{quoted(text)}: {exc}").about(param) from None
    except ValueError:
        raise SearchError(f"{quoted(text)}: COUNT must be a whole number").about(param) from None
    if not all(math.isfinite(v) for v in numbers):
        raise SearchError(f"{quoted(text)}: the values must be finite").about(param)
    if len(numbers) == 1:
        return Axis(canonical, numbers[0], numbers[0], 1)
    low, high = numbers
    if count is not None and count < 1 or high < low or (high == low and count != 1):
        raise SearchError(
            f"{quoted(text)} is an empty range: give LOW < HIGH and a COUNT of 1 or more"
        ).about(param)
    if count is not None and count > MAX_RUNS:
        raise SearchError(f"{quoted(text)}: COUNT must be at most {MAX_RUNS:,}").about(param)
    if count == 1 and high != low:
        raise SearchError(
            f"{quoted(text)}: one value of a range is ambiguous; write {name}=VALUE"
        ).about(param)
    return Axis(canonical, low, high, count)


@dataclass(frozen=True)
class Space:
    """The gait parameters (every one of GAIT_PARAMETERS, fixed or varied) and the
    robustness parameters."""

    params: tuple[Axis, ...]
    robust: tuple[Axis, ...] = ()

    @classmethod
    def parse(cls, params: tuple[str, ...], robust: tuple[str, ...] = ()) -> Space:
        axes = {}
        for text in params:
            axis = parse_axis(text)
            if axis.name in axes:
                raise SearchError(f"{axis.name} is given twice: give it once").about("params")
            axes[axis.name] = axis
        for name, value in DEFAULTS.items():
            axes.setdefault(name, Axis(name, value, value, 1))
        missing = [n for n in REQUIRED if n not in axes]
        if missing:
            raise SearchError(
                "give every serpenoid parameter a value or range: missing "
                + ", ".join(f"{n}=..." for n in missing)
            ).about("params")
        rob = {}
        for text in robust:
            axis = parse_axis(text, robust=True)
            if axis.name in rob:
                raise SearchError(f"{axis.name} is given twice: give it once").about("robust")
            if axis.low < 0 or (axis.low == 0 and axis.name != "rolling"):
                raise SearchError(
                    f"{quoted(text)}: {axis.name} must be "
                    + ("zero or more" if axis.name == "rolling" else "positive")
                ).about("robust")
            rob[axis.name] = axis
        return cls(tuple(axes[n] for n in GAIT_PARAMETERS), tuple(rob.values()))

    @property
    def varied(self) -> tuple[Axis, ...]:
        return tuple(a for a in self.params if not a.fixed)

    def check_world(self, world: str) -> None:
        for axis in self.robust:
            worlds = ROBUST_WORLD[axis.name]
            if world not in worlds:
                raise SearchError(
                    f"{axis.name} applies to the {' and '.join(worlds)} world, "
                    f"not the {world} world: use the {worlds[0]} world or drop it"
                ).about("robust", "world")

    def run_count(self, method: str, samples: int) -> int:
        """How many runs a search of this space makes: its candidates (a grid's points,
        else ``samples``) times its robustness values. Exact, without building a grid."""
        candidates = math.prod(a.count or 1 for a in self.varied) if method == "grid" else samples
        return candidates * math.prod(a.count or 1 for a in self.robust)

    def robust_points(self) -> list[dict[str, float]]:
        """Every combination of the robustness values ([{}] without any)."""
        if not self.robust:
            return [{}]
        grids = np.meshgrid(*(a.values() for a in self.robust), indexing="ij")
        flat = [g.ravel() for g in grids]
        return [
            {a.name: float(f[i]) for a, f in zip(self.robust, flat, strict=True)}
            for i in range(flat[0].size)
        ]

    def point(self, varied: np.ndarray) -> dict[str, float]:
        """The full gait parameters for values of the varied ones (in their order)."""
        out = {a.name: a.low for a in self.params if a.fixed}
        for axis, value in zip(self.varied, varied, strict=True):
            out[axis.name] = float(value)
        return {a.name: out[a.name] for a in self.params}
