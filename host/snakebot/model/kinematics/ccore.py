"""The bridge to the C kinematic core: robot structs, options, and status codes turned
into exceptions that say what went wrong and what to do."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from snakebot.core import ffi, lib
from snakebot.errors import InputError, SnakebotError
from snakebot.model.robots import Friction, Robot

FORMS = {"body": lib.KIN_FORM_BODY, "world": lib.KIN_FORM_WORLD}
METHODS = {"rk4": lib.KIN_RK4, "dopri5": lib.KIN_DOPRI5, "dop853": lib.KIN_DOP853}

_HINTS = {
    lib.KIN_ESINGULAR: "move the joints away from that configuration, or give the wheels "
    "some rolling resistance (friction.rolling or axle_nm > 0 in the robot file) so the "
    "motion is defined",
    lib.KIN_EINADMISSIBLE: "change the joint motion so it crosses the singular configuration "
    "with the admissible joint velocity, or give the wheels rolling resistance "
    "(friction.rolling > 0)",
    lib.KIN_ESTEPSIZE: "loosen the tolerance, or check the motion for a singular configuration",
    lib.KIN_EMAXSTEPS: "shorten the time span or loosen the tolerance",
    lib.KIN_ENONFINITE: "check the inputs for NaN or infinity",
    lib.KIN_EUNSUPPORTED: "use snake3 or trident here, or drive the joints instead "
    "(gait serpenoid)",
    lib.KIN_EGEOMETRY: "fix the robot description's lengths and link count",
    lib.KIN_EINVAL: "this is a bug in the caller: report it",
}


#: Core statuses of a joint motion that ideal wheels cannot follow (a singular crossing:
#: reported, or the step size collapsing at the pole of the body velocity).
SINGULAR_CODES = (lib.KIN_ESINGULAR, lib.KIN_EINADMISSIBLE, lib.KIN_ESTEPSIZE)


class KinematicsError(InputError):
    """A status from the C kinematic core; ``code`` is the KIN_* value."""

    def __init__(self, code: int, context: str = "") -> None:
        self.code = code
        text = ffi.string(lib.kin_strerror(code)).decode()
        where = f" ({context})" if context else ""
        hint = _HINTS.get(code)
        super().__init__(f"{text}{where}" + (f": {hint}" if hint else ""))


class UnsupportedModel(KinematicsError):
    """A model the C core does not have for this robot (KIN_EUNSUPPORTED); the message
    says where the robot's model is."""

    def __init__(self, message: str) -> None:
        self.code = lib.KIN_EUNSUPPORTED
        SnakebotError.__init__(self, message)


class SingularConfiguration(KinematicsError):
    """The configuration is singular (KIN_ESINGULAR) or crossed inadmissibly."""


def check(code: int, context: str = "") -> None:
    """Raise the exception for a C status code (nothing for KIN_OK)."""
    if code == lib.KIN_OK:
        return
    if code in (lib.KIN_ESINGULAR, lib.KIN_EINADMISSIBLE):
        raise SingularConfiguration(code, context)
    raise KinematicsError(code, context)


#: The struct of each (robot, friction) object pair seen lately, by identity: the
#: dataclasses are frozen all the way down, so an object's struct never changes. The
#: entry holds the objects, so that their ids are not reused while it is there.
_BY_IDENTITY: dict[tuple[int, int], tuple[Robot, Friction | None, Any]] = {}
_BY_IDENTITY_MAX = 64


def c_robot(robot: Robot, friction: Friction | None = None) -> Any:
    """A ``kin_robot`` struct for the robot (optionally with other friction coefficients);
    the core only reads it, so one struct serves every call with the same values."""
    held = _BY_IDENTITY.get((id(robot), id(friction)))
    if held is not None and held[0] is robot and held[1] is friction:
        return held[2]  # a whole trajectory's call: the values' key took 15 us of 100
    rb = _c_robot_of(robot, friction)
    if len(_BY_IDENTITY) >= _BY_IDENTITY_MAX:
        _BY_IDENTITY.clear()
    _BY_IDENTITY[id(robot), id(friction)] = (robot, friction, rb)
    return rb


def _c_robot_of(robot: Robot, friction: Friction | None) -> Any:
    if robot.kind not in ("snake", "trident"):
        raise UnsupportedModel(
            f"{robot.name} is a {robot.kind}: only its control fields are modelled "
            f"(snakebot model fields {robot.name}); gaits and the emulator drive snakes "
            "and tridents"
        )
    lateral, rolling = robot.wheel_friction_n(friction)
    # keyed by the values the struct holds, not by the robot (whose hash walks all of
    # it, as long as building the struct): a whole trajectory can take 80 us
    return _c_robot(
        robot.name,
        robot.kind,
        robot.links if robot.kind == "snake" else 0,
        robot.l,
        robot.r,
        tuple(robot.alphas[:3]),
        tuple(float(v) for v in lateral),
        tuple(float(v) for v in rolling),
    )


@functools.lru_cache(maxsize=64)
def _c_robot(
    name: str,
    kind: str,
    links: int,
    l: float,  # noqa: E741 (the model's name for the length)
    r: float,
    alpha: tuple[float, ...],
    lateral: tuple[float, ...],
    rolling: tuple[float, ...],
) -> Any:
    rb = ffi.new(
        "kin_robot *",
        {
            "kind": lib.KIN_SNAKE if kind == "snake" else lib.KIN_TRIDENT,
            "links": links,
            "l": l,
            "r": r,
            "alpha": list(alpha),
            "lateral": list(lateral),
            "rolling": list(rolling),
        },
    )
    code = lib.kin_check_robot(rb, ffi.NULL)
    if code != lib.KIN_OK:
        check(code, f"robot {name}")
    return rb


@dataclass(frozen=True)
class Options:
    """Integrator settings: ``method`` "dopri5" or "dop853" (adaptive Dormand-Prince 5(4)
    and 8(5,3), rtol/atol; the second needs fewer evaluations at tight tolerances, and
    under a joint schedule ends its steps at the wheels' switches between sticking and
    slipping instead of stepping across them) or "rk4" (step h)."""

    method: str = "dopri5"
    rtol: float = 1e-9
    atol: float = 1e-12
    h: float = 0.0
    h_min: float = 0.0
    max_steps: int = 0

    def to_c(self) -> Any:
        """The ``kin_options`` struct (one per distinct settings: the core only reads it)."""
        return _c_options(self)


@functools.lru_cache(maxsize=64)
def _c_options(options: Options) -> Any:
    if options.method not in METHODS:
        raise KinematicsError(
            lib.KIN_EINVAL, f"unknown method {options.method!r}: use one of {', '.join(METHODS)}"
        )
    return ffi.new(
        "kin_options *",
        {
            "method": METHODS[options.method],
            "h": options.h,
            "rtol": options.rtol,
            "atol": options.atol,
            "h_min": options.h_min,
            "max_steps": options.max_steps,
        },
    )


def as_doubles(values: Any, length: int, what: str) -> np.ndarray:
    """A contiguous float64 copy with exactly ``length`` entries (ValueError otherwise)."""
    arr = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
    if arr.size != length:
        raise ValueError(f"{what} needs {length} values, got {arr.size}")
    return arr


def dptr(arr: np.ndarray) -> Any:
    """A ``double[]`` over a contiguous float64 numpy array (what a ``double *`` takes)."""
    return ffi.from_buffer("double[]", arr)
