"""Joint loops and the body motion they make: the planner's building block.

The wheeled robots here are driftless and symmetric under planar motions: the body's
velocity in its own frame depends only on the joint angles and their rates (the
minimum-slip model, linear in the rates). A closed loop in joint space that starts and
ends at a hub configuration therefore moves the body by one fixed pose ``D(loop)``,
wherever the body is and however fast the loop is played; repeating the loop k times
moves it by ``D^k``. This is what the Lie brackets say to first order (a small loop in
the inputs i, j moves along [g_i, g_j] by its area); here the motion is integrated
exactly, by the C core, on the joint path as the controller plays it (straight lines
between frames).

A loop is ``FRAMES`` frames of

    phi(s) = hub + sum_k a_k sin(k s) + b_k (1 - cos(k s)),   s = 0 .. 2 pi,

over ``HARMONICS`` harmonics per joint: it starts and ends at the hub, the b terms move
its centre (the serpenoid's steering offset), the a terms open it. ``solve_loop`` finds
coefficients whose loop moves the body by a wanted pose (nonlinear least squares,
scipy's trust-region reflective solver), keeping every frame inside the joint limits and
away from singular configurations (the wheel model's reciprocal condition number
above the tools' warning threshold).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from snakebot.errors import InputError
from snakebot.model.gait.common import NEAR_SINGULAR_RCOND
from snakebot.model.kinematics import (
    Options,
    Table,
    integrate_joints,
    integrate_joints_batch,
)
from snakebot.model.robots import Robot

FRAMES = 24
"""Frames per loop: fine enough that the played polygon is a smooth loop."""
HARMONICS = 2
#: Accuracy of the integrations inside the solver (the plan's check uses the gait's).
SOLVE_OPTIONS = Options("dopri5", rtol=1e-6, atol=1e-9)
#: How far inside each joint limit a loop stays (radians): room for rounding to ticks.
LIMIT_MARGIN = 0.03
#: Residual of a loop that cannot be integrated (through a singular configuration).
FAILED = 10.0
#: Passes of the single-tick search over a rounded loop's frames.
REFINE_PASSES = 6
#: Solver budget per attempt (function evaluations).
MAX_EVALS = 40
#: Relative step of the Jacobian's forward differences: SciPy's for "2-point".
DIFF_STEP = float(np.finfo(float).eps) ** 0.5


class PlanError(InputError):
    """A plan that cannot be made as asked (bad input or a solver failure)."""


@dataclass(frozen=True)
class Loop:
    """A solved loop: hub angles, coefficients (joints x 2 * HARMONICS), its motion."""

    hub: np.ndarray
    coefficients: np.ndarray
    motion: np.ndarray

    def angles(self) -> np.ndarray:
        return loop_angles(self.hub, self.coefficients)


def loop_angles(hub: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """The loop's frames, first and last at the hub: (FRAMES + 1) x joints. The harmonics
    are as many as the coefficients hold (HARMONICS for a table's loops; a program's
    periodic blocks have one). A stack of coefficient vectors (rows) gives a stack of
    loops, each the same numbers as alone."""
    c = np.asarray(coefficients, dtype=float)
    p = c.reshape(*c.shape[:-1], len(hub), -1)
    out = np.broadcast_to(np.asarray(hub, dtype=float), (*c.shape[:-1], FRAMES + 1, len(hub)))
    out = out.copy()
    for k, (sin_ks, one_minus_cos_ks) in enumerate(_harmonics(p.shape[-1] // 2), start=1):
        out += sin_ks * p[..., None, :, 2 * k - 2] + one_minus_cos_ks * p[..., None, :, 2 * k - 1]
    return out


@functools.cache
def _harmonics(count: int) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
    """Per harmonic k, sin(k s) and 1 - cos(k s) over a loop's frames, as columns: the
    solver builds a loop's frames some hundred thousand times a closed loop."""
    s = np.arange(FRAMES + 1) * (2.0 * math.pi / FRAMES)
    out = []
    for k in range(1, count + 1):
        sin_ks, one_minus_cos_ks = np.sin(k * s)[:, None], (1.0 - np.cos(k * s))[:, None]
        sin_ks.flags.writeable = one_minus_cos_ks.flags.writeable = False
        out.append((sin_ks, one_minus_cos_ks))
    return tuple(out)


def path_motion(robot: Robot, angles: np.ndarray, options: Options = SOLVE_OPTIONS) -> np.ndarray:
    """Body displacement (start frame) while the joints follow ``angles`` frame to frame."""
    return _integrate(robot, angles, options)[0]


def _integrate(
    robot: Robot, angles: np.ndarray, options: Options = SOLVE_OPTIONS
) -> tuple[np.ndarray, float]:
    """The displacement and the path's least reciprocal condition number."""
    rows = len(angles) - 1
    traj = integrate_joints(robot, Table(angles, 1.0), float(rows), samples=2, options=options)
    return traj.q[-1, :3] - traj.q[0, :3], float(traj.stats.get("min_rcond", 1.0))


def path_motions(
    robot: Robot, paths: np.ndarray, options: Options = SOLVE_OPTIONS
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``path_motion`` of a stack of paths (paths x frames x joints) in one call into the
    core: the displacements, each path's least reciprocal condition number, and whether
    it could be integrated at all (where not, its displacement is NaN). Each is the same
    number as its own ``path_motion``."""
    rows = paths.shape[1] - 1
    schedules = [Table(angles, 1.0) for angles in paths]
    batch = integrate_joints_batch(robot, schedules, float(rows), samples=2, options=options)
    return batch.q[:, -1, :3] - batch.q[:, 0, :3], batch.min_rcond, batch.status == 0


def limits(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's allowed range less the margin."""
    lo = np.array([j.min_rad for j in robot.joints]) + LIMIT_MARGIN
    hi = np.array([j.max_rad for j in robot.joints]) - LIMIT_MARGIN
    return lo, hi


def solve_loop(
    robot: Robot,
    hub: np.ndarray,
    wanted: np.ndarray,
    scale: float,
    guesses: list[np.ndarray],
    accuracy: float,
    keep_off: float = NEAR_SINGULAR_RCOND,
    closest: Callable[[np.ndarray], None] | None = None,
) -> Loop | None:
    """A loop through ``hub`` moving the body by ``wanted`` (x, y, theta), or None.

    ``scale`` is the length that weighs position against heading (radians); the first
    guess whose solution reaches ``accuracy`` (scaled residual) wins. The loop keeps off
    configurations whose reciprocal condition number is below ``keep_off``. ``closest``
    is given the coefficients that came nearest, whether or not they reach it."""
    lo, hi = limits(robot)
    weights = np.array([1.0 / scale, 1.0 / scale, 1.0])

    def residuals(stack: np.ndarray) -> np.ndarray:
        """The residual of each row of coefficients (one batch into the core)."""
        angles = loop_angles(hub, stack)
        outside = (np.maximum(angles - hi, 0.0).sum(axis=(1, 2))) + (
            np.maximum(lo - angles, 0.0).sum(axis=(1, 2))
        )
        moved, rcond, integrated = path_motions(robot, angles)
        # near a singular configuration the motion is hypersensitive to rounding: keep off
        near = np.maximum(0.0, keep_off - rcond) / keep_off
        out = np.column_stack(((moved - wanted) * weights, 10.0 * outside, near))
        out[~integrated] = FAILED  # through a singular configuration
        out[~integrated, 3] = 10.0 * outside[~integrated]
        return out

    tight = {"max_nfev": MAX_EVALS, "xtol": 1e-12, "ftol": 1e-12, "gtol": 1e-12}
    p = best_fit(*batched(residuals), guesses, accuracy, closest=closest, **tight)
    if p is None:
        return None
    return Loop(np.asarray(hub, dtype=float), p, path_motion(robot, loop_angles(hub, p)))


def batched(
    residuals: Callable[[np.ndarray], np.ndarray],
    bounds: tuple[Any, Any] = (-np.inf, np.inf),
) -> tuple[Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray]]:
    """A residual function of one parameter vector and its Jacobian (forward
    differences), from ``residuals`` of a stack of them: the differences at all the
    parameters are one stack, one call into the core instead of one per parameter. The
    steps are SciPy's own for "2-point" (the square root of the float epsilon, relative
    to the parameter where it exceeds 1, backwards where forwards would leave
    ``bounds``), so the fit takes the steps it took when SciPy made the differences."""
    last: list[tuple[np.ndarray, np.ndarray]] = []

    def residual(x: np.ndarray) -> np.ndarray:
        f = residuals(np.asarray(x, dtype=float)[None, :])[0]
        last[:] = [(np.array(x, dtype=float), f)]
        return f

    def jacobian(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        # SciPy evaluates the residual at x just before its Jacobian there
        f0 = last[0][1] if last and np.array_equal(last[0][0], x) else residual(x)
        h = DIFF_STEP * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
        below, above = x - bounds[0], bounds[1] - x
        fits = np.abs(h) <= np.maximum(below, above)
        h = np.where(fits & ((x + h < bounds[0]) | (x + h > bounds[1])), -h, h)
        h = np.where(fits, h, np.where(above >= below, above, -below))
        points = np.repeat(x[None, :], len(x), axis=0)
        np.fill_diagonal(points, x + h)
        dx = (x + h) - x
        return ((residuals(points) - f0) / dx[:, None]).T

    return residual, jacobian


def best_fit(
    residual: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray] | str,
    guesses: Iterable[np.ndarray],
    accuracy: float,
    closest: Callable[[np.ndarray], None] | None = None,
    **options: Any,
) -> np.ndarray | None:
    """Least squares from each guess in turn (SciPy's trust-region method, the Jacobian
    ``jacobian`` or SciPy's differences by that name, ``options`` passed on): the first
    solution whose residuals all reach ``accuracy``, else None.
    ``closest``, if given, is called with the solution of least cost found either way."""
    try:
        from scipy.optimize import least_squares  # the planner's optional dependency
    except ImportError:  # pragma: no cover - make setup installs it
        raise PlanError("planning needs SciPy: pip install 'snakebot[plan]'") from None
    best = None
    for guess in guesses:
        sol = least_squares(residual, guess, jac=jacobian, method="trf", x_scale=0.3, **options)
        if best is None or sol.cost < best.cost:
            best = sol
        if np.abs(sol.fun).max() <= accuracy:
            break
    if best is not None and closest is not None:
        closest(np.asarray(best.x))
    if best is None or np.abs(best.fun).max() > accuracy:
        return None
    return np.asarray(best.x)


def refine_ticks(
    robot: Robot, ticks: np.ndarray, wanted: np.ndarray, scale: float, accuracy: float
) -> tuple[np.ndarray, float]:
    """The loop rounded to ticks, nudged frame by frame by single ticks until the loop as
    played moves the body by ``wanted`` to within ``accuracy`` (scaled as in
    ``solve_loop``), or no single tick helps; returns the ticks and their error.

    Rounding moves each frame by up to half a tick, and near the 3-link snake's singular
    line a loop's motion is so sensitive to its frames that this alone can move it by a
    tenth of a body length; the same sensitivity lets a few ticks steer it back. The
    first and last frames (the hub) stay."""
    weights = np.array([1.0 / scale, 1.0 / scale, 1.0])
    limits_t = np.array(robot.tick_limits)
    t = np.array(ticks, dtype=np.int64)

    def errors(stack: np.ndarray) -> list[float]:
        moved, _, integrated = path_motions(robot, robot.ticks_to_angles(stack))
        return [
            float(np.linalg.norm((m - wanted) * weights)) if ok else math.inf
            for m, ok in zip(moved, integrated, strict=True)
        ]

    best = errors(t[None])[0]
    steps: tuple[int, ...] = (1, -1)
    for _ in range(REFINE_PASSES):
        if best <= accuracy:
            break
        improved = False
        for i in range(1, len(t) - 1):
            # joint by joint, the first step that helps is kept; the trials of this frame
            # from the first joint not yet done are one batch, taken again after a step
            # is kept (the joints after it start from it)
            first = 0
            while first < t.shape[1]:
                trials = [
                    (j, step)
                    for j in range(first, t.shape[1])
                    for step in steps
                    if limits_t[j, 0] <= t[i, j] + step <= limits_t[j, 1]
                ]
                stack = np.repeat(t[None], len(trials), axis=0)
                for k, (j, step) in enumerate(trials):
                    stack[k, i, j] += step
                first = t.shape[1]
                for (j, step), e in zip(trials, errors(stack), strict=True):
                    if e < best:
                        t[i, j] += step
                        best, improved, first = e, True, j + 1
                        break
        if not improved:
            if len(steps) > 2:
                break
            steps = (1, -1, 2, -2, 4, -4)  # stuck: try longer strides once more
    return t, best
