"""Whole trajectories through the C core in one call each.

* ``integrate_joints``: joints follow a schedule (``Sines`` or a ``Table`` of samples);
  the body follows through the minimum-slip model (the emulator's and the gait
  predictor's direction).
* ``integrate_fields``: the control system qdot = sum_i u_i(t) g_i(q) with inputs
  u_i = c_i + a_i sin(omega t) + b_i cos(omega t) (``Inputs``).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snakebot.core import ffi, lib
from snakebot.model.kinematics.ccore import (
    KinematicsError,
    Options,
    as_doubles,
    c_robot,
    check,
    dptr,
)
from snakebot.model.kinematics.model import _c_form, field_model
from snakebot.model.robots import Friction, Robot


@dataclass(frozen=True)
class Sines:
    """phi_j(t) = offset_j + rate_j t + amp_j sin(omega t + phase_j)."""

    omega: float
    amp: tuple[float, ...]
    phase: tuple[float, ...]
    offset: tuple[float, ...] = ()
    rate: tuple[float, ...] = ()

    @classmethod
    def serpenoid(
        cls,
        joints: int,
        amplitude: float,
        omega: float,
        delta: float,
        offset: float = 0.0,
        phase: float = 0.0,
    ) -> Sines:
        """phi_k = A sin(omega t + (k - 1) delta + phase) + phi_0 (Hirose's discrete
        serpenoid; ``phase`` is joint 1's phase at t = 0)."""
        return cls(
            omega,
            (amplitude,) * joints,
            tuple(phase + k * delta for k in range(joints)),
            (offset,) * joints,
        )


@dataclass(frozen=True)
class Table:
    """Joint samples (rows x joints, radians) every ``dt`` seconds, linear in between;
    a looping table wraps from its last row to its first (the controller's playback)."""

    samples: np.ndarray
    dt: float
    loop: bool = False


@dataclass(frozen=True)
class Inputs:
    """u_i(t) = c_i + a_i sin(w t) + b_i cos(w t) + a2_i sin(2 w t) + b2_i cos(2 w t)
    for the field-driven system (w = ``omega``); empty tuples mean zeros."""

    c: tuple[float, ...]
    a: tuple[float, ...] = ()
    b: tuple[float, ...] = ()
    omega: float = 0.0
    form: str | None = None
    a2: tuple[float, ...] = ()
    b2: tuple[float, ...] = ()

    def coefficients(self, name: str) -> np.ndarray:
        values = getattr(self, name)
        return np.array(values, dtype=float) if values else np.zeros(len(self.c))

    def at(self, t: np.ndarray) -> np.ndarray:
        """Input values at times t, shape (len(t), inputs)."""
        wt = self.omega * np.asarray(t, dtype=float)[:, None]
        k = self.coefficients
        return (
            k("c")
            + k("a") * np.sin(wt)
            + k("b") * np.cos(wt)
            + k("a2") * np.sin(2 * wt)
            + k("b2") * np.cos(2 * wt)
        )


@dataclass(frozen=True)
class Trajectory:
    """Samples ``q[k]`` = (x, y, theta, phi...) at ``t[k]``; ``slip[k]`` (wheels' normal slip
    speeds, joint-driven only) and the integrator's counters in ``stats``."""

    t: np.ndarray
    q: np.ndarray
    slip: np.ndarray | None = None
    stats: dict[str, float] = field(default_factory=dict)

    @property
    def displacement(self) -> np.ndarray:
        """Final minus initial state."""
        return self.q[-1] - self.q[0]


def _schedule_init(robot: Robot, schedule: Sines | Table) -> tuple[dict[str, Any], list[Any]]:
    """The fields of a ``kin_schedule`` for ``schedule``, and what must outlive it."""
    n = robot.n_joints
    if isinstance(schedule, Sines):
        init: dict[str, Any] = {"type": lib.KIN_SCHED_SINES, "joints": n, "omega": schedule.omega}
        for name in ("amp", "phase", "offset", "rate"):
            values = getattr(schedule, name)
            if values and len(values) != n:
                raise ValueError(
                    f"Sines.{name} needs {n} values for {robot.name}, got {len(values)}"
                )
            init[name] = list(values)
        return init, []
    samples = np.ascontiguousarray(schedule.samples, dtype=np.float64)
    if samples.ndim != 2 or samples.shape[1] != n or samples.shape[0] < 1:
        raise ValueError(f"Table.samples must have shape (rows, {n}), got {samples.shape}")
    init = {
        "type": lib.KIN_SCHED_TABLE,
        "joints": n,
        "samples": dptr(samples),
        "rows": samples.shape[0],
        "dt": schedule.dt,
        "loop": int(schedule.loop),
    }
    return init, [samples]


def _c_schedule(robot: Robot, schedule: Sines | Table) -> tuple[Any, list[Any]]:
    init, keep = _schedule_init(robot, schedule)
    return ffi.new("kin_schedule *", init), keep


def _times(t0: float, t1: float, samples: int) -> np.ndarray:
    """The output times the core uses: t0 + k (t1 - t0) / (samples - 1), t1 exactly last."""
    if samples == 2:  # the common whole-trajectory call: no arithmetic on arrays
        return np.array((t0, t1))
    times = t0 + (t1 - t0) * (np.arange(samples) / (samples - 1))
    times[-1] = t1
    return times


def _stats(st: Any) -> dict[str, float]:
    return {
        "steps": st.steps,
        "rejected": st.rejected,
        "evals": st.evals,
        "fallbacks": st.fallbacks,
        "min_rcond": st.min_rcond,
    }


def schedule_eval(robot: Robot, schedule: Sines | Table, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles and velocities of the schedule at time t."""
    s, _keep = _c_schedule(robot, schedule)
    phi, dphi = np.empty(robot.n_joints), np.empty(robot.n_joints)
    check(lib.kin_schedule_eval(s, t, dptr(phi), dptr(dphi)))
    return phi, dphi


def integrate_joints(
    robot: Robot,
    schedule: Sines | Table,
    t1: float,
    *,
    t0: float = 0.0,
    pose0: tuple[float, float, float] = (0.0, 0.0, 0.0),
    samples: int = 2,
    options: Options | None = None,
    friction: Friction | None = None,
    with_slip: bool = False,
) -> Trajectory:
    """Body pose from t0 to t1 with the joints following ``schedule``; ``samples`` evenly
    spaced output rows (t0 and t1 included)."""
    if samples < 2:
        raise ValueError("samples must be at least 2 (the start and the end)")
    rb = c_robot(robot, friction)
    s, _keep = _c_schedule(robot, schedule)
    opt = (options or Options()).to_c()
    out = np.empty((samples, 3 + robot.n_joints))
    slip = np.empty((samples, robot.n_wheels)) if with_slip else None
    st = ffi.new("kin_stats *")
    p0 = as_doubles(pose0, 3, "pose0")
    code = lib.kin_integrate_joints(
        rb,
        s,
        dptr(p0),
        t0,
        t1,
        samples,
        opt,
        dptr(out),
        dptr(slip) if slip is not None else ffi.NULL,
        st,
    )
    if code != lib.KIN_OK:
        check(code, f"{robot.name}, joint schedule, at t = {st.t_fail:.6g} s")
    return Trajectory(_times(t0, t1, samples), out, slip, _stats(st))


@dataclass(frozen=True)
class Batch:
    """Trajectories of one robot under many schedules: ``q[k, i]`` is the state at ``t[i]``
    under schedule k; ``status[k]`` is 0 where it ran to the end, else the core's error
    code (``q[k]`` is then NaN); ``evals[k]`` counts its right-hand-side evaluations and
    ``min_rcond[k]`` is the least reciprocal condition number of the wheel model on its way
    (``Trajectory.stats["min_rcond"]`` of a single call)."""

    t: np.ndarray
    q: np.ndarray
    status: np.ndarray
    evals: np.ndarray
    min_rcond: np.ndarray

    def error(self, k: int) -> str | None:
        """Why trajectory k failed, in words (None if it did not)."""
        code = int(self.status[k])
        return None if code == lib.KIN_OK else str(KinematicsError(code))


def integrate_joints_batch(
    robot: Robot,
    schedules: Sequence[Sines | Table],
    t1: float,
    *,
    t0: float = 0.0,
    pose0: tuple[float, float, float] = (0.0, 0.0, 0.0),
    samples: int = 2,
    options: Options | None = None,
    friction: Friction | None = None,
) -> Batch:
    """``integrate_joints`` for every schedule in one call into the core, no Python between
    trajectories (a parameter grid, a gait search's batch); a failed trajectory does not
    stop the others."""
    if samples < 2:
        raise ValueError("samples must be at least 2 (the start and the end)")
    inits, keep = [], []
    for schedule in schedules:
        init, kept = _schedule_init(robot, schedule)
        inits.append(init)
        keep += kept
    count = len(inits)
    s = ffi.new("kin_schedule[]", inits) if count else ffi.NULL
    out = np.empty((count, samples, 3 + robot.n_joints))
    status = np.zeros(count, dtype=np.int32)
    stats = ffi.new("kin_stats[]", max(count, 1))
    p0 = as_doubles(pose0, 3, "pose0")
    code = lib.kin_integrate_joints_batch(
        c_robot(robot, friction),
        s,
        count,
        dptr(p0),
        t0,
        t1,
        samples,
        (options or Options()).to_c(),
        dptr(out),
        ffi.from_buffer("int32_t[]", status) if count else ffi.NULL,
        stats,
    )
    if code == lib.KIN_EINVAL and not status.any():
        check(code, f"{robot.name}, batch of {count} schedules")
    out[status != lib.KIN_OK] = np.nan
    evals = np.array([stats[k].evals for k in range(count)], dtype=np.int64)
    min_rcond = np.array([stats[k].min_rcond for k in range(count)], dtype=float)
    return Batch(_times(t0, t1, samples), out, status, evals, min_rcond)


#: The default start q0 = 0 (the core only reads it): no array built for each call.
_ZERO_STATE = ffi.new("double[]", lib.KIN_MAX_STATE)


def integrate_fields(
    robot: Robot,
    inputs: Inputs,
    t1: float,
    *,
    q0: np.ndarray | None = None,
    t0: float = 0.0,
    samples: int = 2,
    options: Options | None = None,
) -> Trajectory:
    """The field-driven system from q0 (default 0) at t0 to t1; ``samples`` evenly spaced
    output rows (t0 and t1 included)."""
    field_model(robot)
    if samples < 2:
        raise ValueError("samples must be at least 2 (the start and the end)")
    n = 3 + robot.n_joints
    key = (robot.name, 2 if robot.kind == "snake" else 3, _c_form(robot, inputs.form), inputs)
    try:
        u = _c_inputs(*key)
    except TypeError:  # inputs holding lists: unhashable, built for this call only
        u = _c_inputs.__wrapped__(*key)
    q0_c = _ZERO_STATE if q0 is None else dptr(as_doubles(q0, n, "q0"))
    out = np.empty((samples, n))
    st = ffi.new("kin_stats *")
    code = lib.kin_integrate_fields(
        c_robot(robot), u, q0_c, t0, t1, samples, (options or Options()).to_c(), dptr(out), st
    )
    if code != lib.KIN_OK:
        check(code, f"{robot.name}, field inputs, at t = {st.t_fail:.6g} s")
    return Trajectory(_times(t0, t1, samples), out, None, _stats(st))


@functools.lru_cache(maxsize=64)
def _c_inputs(name: str, m: int, form: int, inputs: Inputs) -> Any:
    """The ``kin_inputs`` struct of ``inputs`` for a robot with ``m`` inputs (the core
    only reads it: one per distinct inputs, not one per trajectory)."""
    init: dict[str, Any] = {"form": form, "omega": inputs.omega}
    for field_name in ("c", "a", "b", "a2", "b2"):
        values = getattr(inputs, field_name)
        if values and len(values) != m:
            raise KinematicsError(
                lib.KIN_EINVAL, f"{name} has {m} inputs: Inputs.{field_name} has {len(values)}"
            )
        init[field_name] = list(values)
    return ffi.new("kin_inputs *", init)
