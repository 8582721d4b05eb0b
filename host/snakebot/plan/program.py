"""Plans written as controller programs (``snakebot plan ... -o FILE.prog``): the same
route as a table plan (start -> hub, k loops, hub -> start; ``planner``), each part an
on-board generator, so a plan costs a hundred bytes or so instead of a table's kilobyte.

- the start is held for one step, absolute (a periodic block at omega 0: its cosine
  amplitude is the start angle), and the moves to and from the hub are periodic blocks
  with an offset rate only: straight joint moves, as the table's ramps;
- the k loops are one segment: for the trident and the 3-link snake a periodic block
  with one harmonic per joint (``phi = hub + a sin s + b (1 - cos s)``, the field and
  bracket motion), fitted by ``loops.solve_loop``; for N-link snakes first a serpenoid
  (``a_j = A cos j delta``, ``b_j = -A sin j delta``: the wave started at the hub, its
  offsets the hub less ``A sin j delta``), the amplitude, phase step and a common offset
  fitted to the target, else the one-harmonic block.

The program's carry (protocol/program.md) makes each segment start where the previous
one was heading, so only the hold is absolute. Rounding (mrad, mrad/s, a whole number of
steps per loop, goals to ticks at every step) moves the end a little: the end pose is
integrated from the reference goals the controller sends (``program.motion.end_pose``)
and the loop's wanted motion corrected by the error a few times; a program still outside
the tolerance is refused (``Unreachable``), never written.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from snakebot.gait.field import SPEED_MARGIN
from snakebot.kinematics import KinematicsError
from snakebot.plan import se2
from snakebot.plan.loops import (
    LIMIT_MARGIN,
    PlanError,
    limits,
    loop_angles,
    path_motion,
    refine_ticks,
)
from snakebot.plan.planner import (
    DEFAULT_HEADING_TOLERANCE,
    DEFAULT_TOLERANCE,
    Tolerance,
    Unreachable,
    body_length,
    default_start,
    frame_period_ms,
    hubs,
    loop_counts,
    loop_target,
    pose_dict,
    pose_error,
    ramp,
    routes,
    solve_accuracy,
    validate_start,
)
from snakebot.program import (
    PeriodicSegment,
    Program,
    ProgramError,
    SerpenoidSegment,
    TableSegment,
    check,
)
from snakebot.program.layout import Block, Segment
from snakebot.program.motion import end_pose
from snakebot.program.spec import joints_of
from snakebot.robots import Robot
from snakebot.sim.controller_pty import TICK_MS

MRAD = 1000.0
#: Loops at most in one program (the loop segment's steps fit a u16).
MAX_STEPS = 0xFFFF
#: Steps per loop at least: the wave sampled finely enough to follow the fit.
MIN_LOOP_STEPS = 24
#: Loop counts a periodic route is fitted for: the nominal one and its doublings.
PERIODIC_COUNTS = 3
#: Corrections of the loop's wanted motion by the program's integrated end error.
CORRECTIONS = 8


@dataclass(frozen=True)
class ProgramPlan:
    """A plan as a program and what is known about it."""

    robot: Robot
    target: np.ndarray
    tolerance: Tolerance
    program: Program
    hub: np.ndarray
    loops: int
    loop_kind: str
    reached: np.ndarray

    @property
    def error(self) -> tuple[float, float]:
        return pose_error(self.reached, self.target)

    @property
    def within(self) -> bool:
        return self.tolerance.admits(self.error)

    def summary(self) -> dict[str, Any]:
        p = self.program
        return {
            "robot": self.robot.name,
            "target": pose_dict(self.target),
            "predicted_final": pose_dict(self.reached),
            "error": self.tolerance.report(self.error),
            "hub_rad": self.hub.tolist(),
            "loops": self.loops,
            "loop_kind": self.loop_kind,
            "segments": [_describe(s) for s in p.segments],
            "program_bytes": len(p.encode()),
            "steps": p.total_steps,
            "step_period_ms": p.period_ms,
            "duration_s": round(p.duration_s, 6),
            "warnings": [],
        }


def _describe(segment: Segment) -> dict[str, Any]:
    kind = {TableSegment: "table", SerpenoidSegment: "serpenoid", PeriodicSegment: "periodic"}
    return {"kind": kind[type(segment)], "steps": segment.steps}


def _mrad(value: float) -> int:
    scaled = round(value * MRAD)
    if not -32768 <= scaled <= 32767:
        raise PlanError(f"{value:g} is beyond what a program holds")
    return scaled


def _ramp_steps(robot: Robot, a: np.ndarray, b: np.ndarray, period_ms: int) -> int:
    """Program steps for a straight move from a to b at the gait's speed margin."""
    seconds = float(np.abs(b - a).max()) / (SPEED_MARGIN * robot.max_speed_rad_s)
    return max(1, math.ceil(seconds * 1000.0 / period_ms - 1e-9))


def loop_timing(robot: Robot, coefficients: np.ndarray) -> tuple[int, int]:
    """(steps per loop, omega in mrad/s) for a one-harmonic loop stepped every TICK_MS:
    the fewest steps that keep the peak joint speed ``omega (|a| + |b|)`` inside the
    speed margin, nudged (up to a tenth more) to where 2 pi / (steps * period) is nearest
    a whole mrad/s, so that k loops end nearest the hub."""
    p = np.abs(np.asarray(coefficients).reshape(robot.n_joints, 2)).sum(axis=1).max()
    fastest = SPEED_MARGIN * robot.max_speed_rad_s
    least = max(MIN_LOOP_STEPS, math.ceil(2.0 * math.pi * p / fastest * 1000.0 / TICK_MS))

    def omega_of(n: int) -> float:
        return 2.0 * math.pi * MRAD * 1000.0 / (n * TICK_MS)

    steps = min(
        range(least, least + least // 10 + 1),
        key=lambda n: abs(omega_of(n) - round(omega_of(n))),
    )
    return steps, round(omega_of(steps))


class _Builder:
    """Segments and periodic blocks appended in order (protocol/program.md)."""

    def __init__(self, period_ms: int) -> None:
        self.period_ms = period_ms
        self.segments: list[Segment] = []
        self.blocks: list[Block] = []

    def periodic(self, block: Block, omega: int, steps: int) -> None:
        if block not in self.blocks:
            self.blocks.append(block)
        self.segments.append(PeriodicSegment(self.blocks.index(block), omega, steps))

    def ramp(self, robot: Robot, a: np.ndarray, b: np.ndarray) -> None:
        """A straight move from a to b: an offset rate only."""
        if np.allclose(a, b):
            return
        steps = _ramp_steps(robot, a, b, self.period_ms)
        seconds = steps * self.period_ms / 1000.0
        self.periodic(
            tuple((_mrad((y - x) / seconds), 0, 0) for x, y in zip(a, b, strict=True)), 0, steps
        )


def build_program(robot: Robot, start: np.ndarray, shape: Shape, k: int) -> Program:
    """The program: hold the start (absolute: a periodic block at omega 0 whose cosine
    amplitude is the start), move to the hub, k loops, move back; ProgramError if the
    controller's check refuses it (its range check is conservative)."""
    frames: tuple[tuple[int, ...], ...] = ()
    if shape.ticks is None:
        build = _Builder(TICK_MS)
    else:
        build = _Builder(frame_period_ms(robot, robot.ticks_to_angles(shape.ticks)))
    build.periodic(tuple((0, 0, _mrad(v)) for v in start), 0, 1)
    build.ramp(robot, start, shape.hub)
    if shape.ticks is None:
        per_loop, omega = loop_timing(robot, shape.coefficients)
        if per_loop * k > MAX_STEPS:
            raise PlanError(f"{k} loops of {per_loop} steps do not fit one segment")
        build.periodic(
            tuple((0, _mrad(a), _mrad(-b)) for a, b in shape.coefficients), omega, per_loop * k
        )
    else:
        frames = tuple(tuple(int(v) for v in row) for row in shape.ticks[:-1])
        build.segments.append(TableSegment(0, len(frames), k))
    build.ramp(robot, shape.hub, start)
    program = Program(
        build.period_ms, joints_of(robot), tuple(build.segments), tuple(build.blocks), frames
    )
    check(program.encode())
    return program


@dataclass(frozen=True)
class Shape:
    """A route's loop: its kind, hub and per joint coefficients (a, b per harmonic);
    a table loop also has its frames in ticks (first and last at the hub)."""

    kind: str
    hub: np.ndarray
    coefficients: np.ndarray
    ticks: np.ndarray | None = None

    @classmethod
    def periodic(cls, robot: Robot, x: np.ndarray) -> Shape:
        """A one-harmonic loop from the fit's parameters (hub, coefficients)."""
        n = robot.n_joints
        return cls("periodic", np.asarray(x[:n]), np.asarray(x[n:]).reshape(n, 2))

    def angles(self) -> np.ndarray:
        return loop_angles(self.hub, self.coefficients.ravel())


def route_motion(robot: Robot, start: np.ndarray, shape: Shape, k: int) -> np.ndarray:
    """Where the route (to the hub, k loops as their frames, back) takes the body."""
    moves = not np.allclose(start, shape.hub)
    out = path_motion(robot, ramp(start, shape.hub)) if moves else np.zeros(3)
    one = path_motion(robot, shape.angles())
    for _ in range(k):
        out = se2.compose(out, one)
    if moves:
        out = se2.compose(out, path_motion(robot, ramp(shape.hub, start)))
    return out


def fit_route(
    robot: Robot,
    start: np.ndarray,
    target: np.ndarray,
    k: int,
    guesses: list[np.ndarray],
    accuracy: float,
) -> np.ndarray | None:
    """The parameters (hub, one-harmonic coefficients) of a route with k loops that
    ends at ``target`` (the loops' frames inside the limits less the margin): the first
    guess's solution within ``accuracy`` (scaled residual per loop), or None."""
    try:
        from scipy.optimize import least_squares  # the planner's optional dependency
    except ImportError:  # pragma: no cover - make setup installs it
        raise PlanError("planning needs SciPy: pip install 'snakebot[plan]'") from None
    lo, hi = limits(robot)
    scale = body_length(robot)
    weights = np.array([1.0 / scale, 1.0 / scale, 1.0]) / k

    def residual(x: np.ndarray) -> np.ndarray:
        shape = Shape.periodic(robot, x)
        angles = np.vstack([shape.angles(), shape.hub[None, :]])
        outside = np.maximum(angles - hi, 0).sum() + np.maximum(lo - angles, 0).sum()
        try:
            d = route_motion(robot, start, shape, k) - target
        except KinematicsError:
            return np.r_[np.full(3, 10.0), 10.0 * outside]
        d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
        return np.r_[d * weights, 10.0 * outside]

    best = None
    for guess in guesses:
        sol = least_squares(residual, guess, method="trf", max_nfev=80, x_scale=0.3)
        if best is None or sol.cost < best.cost:
            best = sol
        if np.abs(sol.fun).max() <= accuracy:
            break
    if best is None or np.abs(best.fun).max() > accuracy:
        return None
    return np.asarray(best.x)


def _guesses(robot: Robot, start: np.ndarray) -> list[np.ndarray]:
    """Starting parameters at each of the planner's hubs: a small loop of each joint a
    quarter turn after the last, either way round."""
    n = robot.n_joints
    out = []
    for hub in hubs(robot, start):
        for sign in (1.0, -1.0):
            c = [
                (0.15 * math.cos(j * math.pi / 2), sign * 0.15 * math.sin(j * math.pi / 2))
                for j in range(n)
            ]
            out.append(np.r_[hub, np.ravel(c)])
    return out


def _realise(
    robot: Robot, start: np.ndarray, target: np.ndarray, tol: Tolerance, k: int, shape: Shape
) -> ProgramPlan | None:
    """The route as a program; while its goals (as the controller rounds them) end
    outside the tolerance, the loop is made again for a target moved by the error: a
    periodic loop fitted again, a table loop's ticks nudged (``refine_ticks``)."""
    accuracy = solve_accuracy(robot, tol)
    aim = target
    best: ProgramPlan | None = None
    for attempt in range(CORRECTIONS + 1):
        try:
            program = build_program(robot, start, shape, k)
        except (ProgramError, PlanError):
            return best
        reached = end_pose(robot, program)
        plan = ProgramPlan(robot, target, tol, program, shape.hub, k, shape.kind, reached)
        if best is None or plan.error[0] / tol.position < best.error[0] / tol.position:
            best = plan
        if plan.within or attempt == CORRECTIONS:
            break
        aim = se2.compose(aim, se2.relative(reached, target))
        if shape.ticks is not None:
            wanted = loop_target(robot, start, shape.hub, aim, k)
            ticks, _ = refine_ticks(robot, shape.ticks, wanted, body_length(robot), accuracy)
            shape = replace(shape, ticks=ticks)
            continue
        x = np.r_[shape.hub, shape.coefficients.ravel()]
        refit = fit_route(robot, start, aim, k, [x], accuracy)
        if refit is None:
            break
        shape = Shape.periodic(robot, refit)
    return best


def _periodic_shapes(
    robot: Robot, start: np.ndarray, target: np.ndarray, accuracy: float
) -> Iterator[tuple[int, Shape]]:
    """One-harmonic routes (periodic blocks) for a nominal loop count and its doublings."""
    nominal = loop_counts(robot, target, MAX_STEPS)[0]
    for k in [nominal * 2**i for i in range(PERIODIC_COUNTS)]:
        x = fit_route(robot, start, target, k, _guesses(robot, start), accuracy)
        if x is not None:
            yield k, Shape.periodic(robot, x)


def _table_shapes(
    robot: Robot, start: np.ndarray, target: np.ndarray, tol: Tolerance
) -> Iterator[tuple[int, Shape]]:
    """The table planner's routes (two harmonics: no on-board generator) as table loops."""
    for route in routes(robot, start, target, tol):
        loop = route.loop
        ticks = robot.angles_to_ticks(loop.angles())
        yield route.count, Shape("table", loop.hub, loop.coefficients, ticks)


def plan_program(
    robot: Robot,
    target: tuple[float, float, float],
    *,
    start: tuple[float, ...] | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    heading_tolerance: float = DEFAULT_HEADING_TOLERANCE,
) -> ProgramPlan:
    """A program taking ``robot`` from rest at ``start`` to ``target`` whose goals, as the
    controller sends them, end within the tolerance; Unreachable otherwise."""
    goal = np.asarray(target, dtype=float)
    if goal.shape != (3,) or not np.all(np.isfinite(goal)):
        raise PlanError("--to needs three finite numbers X,Y,THETA")
    phi0 = default_start(robot) if start is None else np.asarray(start, dtype=float)
    validate_start(robot, phi0)
    tol = Tolerance.for_target(robot, goal, tolerance, heading_tolerance)
    best: ProgramPlan | None = None
    accuracy = solve_accuracy(robot, tol)
    for k, shape in itertools.chain(
        _periodic_shapes(robot, phi0, goal, accuracy), _table_shapes(robot, phi0, goal, tol)
    ):
        plan = _realise(robot, phi0, goal, tol, k, shape)
        if plan is None:
            continue
        if best is None or plan.error[0] / tol.position < best.error[0] / tol.position:
            best = plan
        if plan.within:
            return plan
    if best is None:
        raise Unreachable(
            f"no program for {robot.name} reaches x = {goal[0]:.4g}, y = {goal[1]:.4g}, "
            f"theta = {math.degrees(goal[2]):.1f} deg inside its joint limits (with "
            f"{LIMIT_MARGIN} rad to spare) and servo speed: choose a nearer target, or "
            "write a table (-o FILE.gait); no file was written"
        )
    d, h = best.error
    raise Unreachable(
        f"the best program for {robot.name} ends {d:.3g} from the target and "
        f"{math.degrees(h):.2f} deg off its heading once its goals are rounded as the "
        f"controller rounds them, outside the tolerance ({tol.position:.3g}, "
        f"{math.degrees(tol.heading):.2f} deg): loosen --tolerance or write a table "
        "(-o FILE.gait); no file was written"
    )


__all__ = ["ProgramPlan", "plan_program"]
