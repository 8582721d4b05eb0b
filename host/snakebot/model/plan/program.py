"""Plans written as controller programs (``snakebot plan ... -o FILE.prog``): routes like
the table plan's (start -> hub, k loops, back; ``planner``), each part an on-board
generator, so a plan costs a couple of hundred bytes instead of a table's kilobytes.

- the start is held for one step, absolute (a periodic block at omega 0: its cosine
  amplitude is the start angle), and every straight joint move (to a hub, between hubs,
  back to the start) is a periodic block with an offset rate only;
- N-link snakes go by **serpenoid segments with their offsets**: two arcs of k waves
  each, ``phi_j = psi_i + A sin(omega t + j delta)``, the offset psi_i steering arc i,
  reached by a straight move (the segment's carry then keeps it); A, delta, psi_1 and
  psi_2 are fitted to the target;
- the trident and the 3-link snake (and a snake the serpenoid does not reach) go by
  field and bracket motions: one periodic-input block per joint, one harmonic,
  ``phi = hub + a sin s + b (1 - cos s)``, fitted with its hub;
- where no one-harmonic loop reaches the target (the 3-link snake, often), the table
  plan's two-harmonic loop, which no on-board generator makes, is a table segment.

The loops are fitted on their frames, as the table planner's (``loops``), with the exact
motion; the program differs by its rounding (mrad, mrad/s, a whole number of steps per
loop, goals to ticks at every step), so its end pose is integrated from the goals the
controller sends (``model.motion.end_pose``) and the route fitted again to a target
moved by the error a few times; a program still outside the tolerance is refused
(``Unreachable``), never written.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from snakebot.formats.program import (
    PeriodicSegment,
    Program,
    ProgramError,
    SerpenoidSegment,
    TableSegment,
    check,
)
from snakebot.formats.program.layout import Block, Segment
from snakebot.model.gait.field import SPEED_MARGIN
from snakebot.model.motion import end_pose
from snakebot.model.plan import se2
from snakebot.model.plan.loops import (
    LIMIT_MARGIN,
    PlanError,
    batched,
    best_fit,
    limits,
    loop_angles,
    path_motions,
    refine_ticks,
)
from snakebot.model.plan.planner import (
    EndsNearTarget,
    PlanRequest,
    Tolerance,
    body_length,
    capacity_words,
    frame_period_ms,
    hubs,
    loop_counts,
    loop_target,
    out_of_reach,
    pose_dict,
    ramp,
    routes,
    same_joints,
    solve_accuracy,
)
from snakebot.model.player import TICK_MS
from snakebot.model.program_spec import joints_of
from snakebot.model.robots import Robot

MRAD = 1000.0
#: The most steps a segment has (a u16).
MAX_STEPS = 0xFFFF
#: Steps per loop at least: the wave sampled finely enough to follow the fit.
MIN_LOOP_STEPS = 24
#: Loop counts a route is fitted for: the nominal one and its doublings.
COUNTS = 3
#: Fits of the route to a target moved by the program's integrated end error.
CORRECTIONS = 8
#: The serpenoid's amplitude range (rad) and its offsets' (the joints' own limits
#: bound them further, through the fit's penalty).
SERPENOID_AMPLITUDE = (0.05, 1.2)
SERPENOID_OFFSET = 1.2


@dataclass(frozen=True)
class Wave:
    """k loops through a hub: per joint one-harmonic coefficients (a, b); a serpenoid's
    A and delta when it is one; a table loop's frames (ticks, first and last at the hub)
    and its two-harmonic coefficients instead."""

    hub: np.ndarray
    coefficients: np.ndarray
    count: int
    serpenoid: tuple[float, float] | None = None
    ticks: np.ndarray | None = None

    def angles(self) -> np.ndarray:
        return loop_angles(self.hub, np.ravel(self.coefficients))


@dataclass(frozen=True)
class Route:
    """From the start through each wave's hub and back: ``kind`` names how its loops
    are made (serpenoid, periodic or table)."""

    kind: str
    start: np.ndarray
    waves: tuple[Wave, ...]

    @classmethod
    def fitted(cls, robot: Robot, start: np.ndarray, kind: str, k: int, x: np.ndarray) -> Route:
        """The route a fit's parameters describe: a serpenoid's (A, delta, psi_1, psi_2),
        each arc's hub the wave's phase 0 about start + psi_i; a periodic loop's (hub,
        coefficients)."""
        n = robot.n_joints
        if kind == "serpenoid":
            amplitude, delta, *offsets = x
            j = np.arange(n)
            c = np.column_stack([amplitude * np.cos(j * delta), -amplitude * np.sin(j * delta)])
            shift = amplitude * np.sin(j * delta)
            waves = tuple(Wave(start + psi + shift, c, k, (amplitude, delta)) for psi in offsets)
            return cls(kind, start, waves)
        return cls(kind, start, (Wave(np.asarray(x[:n]), np.asarray(x[n:]).reshape(n, 2), k),))

    @property
    def hubs(self) -> list[np.ndarray]:
        return [w.hub for w in self.waves]

    def moves(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The straight moves: to the first hub, between hubs, back to the start."""
        points = [self.start, *self.hubs, self.start]
        return list(itertools.pairwise(points))

    def paths(self) -> list[tuple[np.ndarray, int | None]]:
        """The joint paths in order, each with its loop count (None for a straight move,
        which a route makes once)."""
        out: list[tuple[np.ndarray, int | None]] = []
        for (a, b), wave in itertools.zip_longest(self.moves(), self.waves):
            if not same_joints(a, b):
                out.append((ramp(a, b), None))
            if wave is not None:
                out.append((wave.angles(), wave.count))
        return out


def route_motions(
    robot: Robot, routes: list[Route], known: dict[bytes, tuple[np.ndarray, bool]]
) -> tuple[np.ndarray, np.ndarray]:
    """Each route's motion and whether it could be integrated: the paths of all the
    routes integrated in one call into the core per path length (``path_motions``), each
    the same number as alone, then composed route by route. ``known`` holds the motions
    of paths integrated before (by their frames), and takes the new ones: the routes of
    one fit's differences share most of their paths (a step in a loop's coefficients
    leaves the moves to and from its hub as they were)."""
    paths = [route.paths() for route in routes]
    keys = [angles.tobytes() for route in paths for angles, _ in route]
    flat = dict(zip(keys, (angles for route in paths for angles, _ in route), strict=True))
    by_length: dict[int, list[bytes]] = {}
    for key, angles in flat.items():
        if key not in known:
            by_length.setdefault(len(angles), []).append(key)
    for new in by_length.values():
        moved, _, integrated = path_motions(robot, np.stack([flat[key] for key in new]))
        known.update(zip(new, zip(moved, integrated, strict=True), strict=True))
    out, fine = np.zeros((len(routes), 3)), np.ones(len(routes), dtype=bool)
    steps = iter(keys)
    for r, route in enumerate(paths):
        for _, count in route:
            moved, integrated = known[next(steps)]
            out[r] = se2.compose(out[r], moved if count is None else _power(moved, count))
            fine[r] &= integrated
    return out, fine


def _power(g: np.ndarray, k: int) -> np.ndarray:
    """g composed with itself k times (by squaring: a route may have thousands of loops)."""
    out = np.zeros(3)
    while k:
        if k & 1:
            out = se2.compose(out, g)
        g = se2.compose(g, g)
        k >>= 1
    return out


@dataclass(frozen=True)
class ProgramPlan(EndsNearTarget):
    """A plan as a program and what is known about it."""

    robot: Robot
    target: np.ndarray
    tolerance: Tolerance
    program: Program
    route: Route
    reached: np.ndarray
    capacity: int
    """The capacity (bytes) the program was made for; it fits it."""

    def summary(self) -> dict[str, Any]:
        p = self.program
        return {
            "robot": self.robot.name,
            "target": pose_dict(self.target),
            "predicted_final": pose_dict(self.reached),
            "error": self.tolerance.report(self.error),
            "hubs_rad": [h.tolist() for h in self.route.hubs],
            "loops": sum(w.count for w in self.route.waves),
            "loop_kind": self.route.kind,
            "segments": [_describe(s) for s in p.segments],
            "program_bytes": len(p.encode()),
            "capacity_bytes": self.capacity,
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


def loop_timing(robot: Robot, coefficients: np.ndarray) -> tuple[int, int]:
    """(steps per loop, omega in mrad/s) for a one-harmonic loop stepped every TICK_MS:
    the fewest steps that keep the peak joint speed, at most ``omega (|a| + |b|)``,
    inside the speed margin, nudged (up to a tenth more) to where 2 pi / (steps * period)
    is nearest a whole mrad/s, so that k loops end nearest the hub."""
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

    def __init__(self, robot: Robot, period_ms: int) -> None:
        self.robot = robot
        self.period_ms = period_ms
        self.segments: list[Segment] = []
        self.blocks: list[Block] = []

    def periodic(self, block: Block, omega: int, steps: int) -> None:
        if block not in self.blocks:
            self.blocks.append(block)
        self.segments.append(PeriodicSegment(self.blocks.index(block), omega, steps))

    def move(self, a: np.ndarray, b: np.ndarray) -> None:
        """A straight move from a to b at the gait's speed margin: an offset rate only."""
        if np.allclose(a, b):
            return
        seconds = float(np.abs(b - a).max()) / (SPEED_MARGIN * self.robot.max_speed_rad_s)
        steps = max(1, math.ceil(seconds * 1000.0 / self.period_ms - 1e-9))
        seconds = steps * self.period_ms / 1000.0
        rates = tuple((_mrad((y - x) / seconds), 0, 0) for x, y in zip(a, b, strict=True))
        self.periodic(rates, 0, steps)

    def loops(self, wave: Wave) -> None:
        if wave.ticks is not None:  # the frames are the program's own table
            self.segments.append(TableSegment(0, len(wave.ticks) - 1, wave.count))
            return
        per_loop, omega = loop_timing(self.robot, wave.coefficients)
        steps = per_loop * wave.count
        if steps > MAX_STEPS:
            raise PlanError(f"{wave.count} loops of {per_loop} steps do not fit one segment")
        if wave.serpenoid is not None:
            amplitude, delta = wave.serpenoid
            self.segments.append(SerpenoidSegment(_mrad(amplitude), omega, _mrad(delta), 0, steps))
            return
        block = tuple((0, _mrad(a), _mrad(-b)) for a, b in wave.coefficients)
        self.periodic(block, omega, steps)


def build_program(robot: Robot, route: Route) -> Program:
    """The route as a program: the start held (absolute), each straight move and each
    wave's loops a segment; ProgramError if the controller's check refuses it (its
    range check is conservative)."""
    table = next((w.ticks for w in route.waves if w.ticks is not None), None)
    period = TICK_MS if table is None else frame_period_ms(robot, robot.ticks_to_angles(table))
    build = _Builder(robot, period)
    build.periodic(tuple((0, 0, _mrad(v)) for v in route.start), 0, 1)
    for (a, b), wave in itertools.zip_longest(route.moves(), route.waves):
        build.move(a, b)
        if wave is not None:
            build.loops(wave)
    frames = () if table is None else tuple(tuple(int(v) for v in row) for row in table[:-1])
    program = Program(period, joints_of(robot), tuple(build.segments), tuple(build.blocks), frames)
    check(program.encode())
    return program


def fit_route(
    robot: Robot,
    start: np.ndarray,
    target: np.ndarray,
    kind: str,
    k: int,
    guesses: list[np.ndarray],
    accuracy: float,
) -> np.ndarray | None:
    """The parameters of a ``kind`` route with k loops a wave that ends at ``target``
    (the loops' frames inside the limits less the margin): the first guess's solution
    within ``accuracy`` (scaled residual per loop), or None."""
    lo, hi = limits(robot)
    weights = np.array([1.0 / body_length(robot), 1.0 / body_length(robot), 1.0]) / k
    bounds: tuple[Any, Any] = (-np.inf, np.inf)
    if kind == "serpenoid":
        low, high = SERPENOID_AMPLITUDE
        bounds = (
            [low, -math.pi, *[-SERPENOID_OFFSET] * 2],
            [high, math.pi, *[SERPENOID_OFFSET] * 2],
        )

    known: dict[bytes, tuple[np.ndarray, bool]] = {}

    def residuals(stack: np.ndarray) -> np.ndarray:
        """The residual of each row of parameters (one batch into the core)."""
        routes = [Route.fitted(robot, start, kind, k, x) for x in stack]
        angles = np.array([np.vstack([w.angles() for w in route.waves]) for route in routes])
        outside = np.maximum(angles - hi, 0).sum(axis=(1, 2)) + np.maximum(lo - angles, 0).sum(
            axis=(1, 2)
        )
        moved, integrated = route_motions(robot, routes, known)
        d = moved - target
        d[:, 2] = (d[:, 2] + math.pi) % (2 * math.pi) - math.pi
        out = np.column_stack((d * weights, 10.0 * outside))
        out[~integrated, :3] = 10.0
        return out

    residual, jacobian = batched(residuals, bounds)
    return best_fit(residual, jacobian, guesses, accuracy, max_nfev=80, bounds=bounds)


def _guesses(robot: Robot, start: np.ndarray, kind: str) -> list[np.ndarray]:
    """Starting parameters: a serpenoid's, turning one way then the other; a periodic
    loop's at each of the planner's hubs, a small loop of each joint a quarter turn
    after the last, either way round."""
    if kind == "serpenoid":
        return [np.array(g) for g in ((0.5, 1.0, 0.1, -0.1), (0.5, 1.0, -0.1, 0.1))]
    out = []
    for hub in hubs(robot, start):
        for sign in (1.0, -1.0):
            c = [
                (0.15 * math.cos(j * math.pi / 2), sign * 0.15 * math.sin(j * math.pi / 2))
                for j in range(robot.n_joints)
            ]
            out.append(np.r_[hub, np.ravel(c)])
    return out


def _fitted_routes(
    robot: Robot, start: np.ndarray, target: np.ndarray, accuracy: float
) -> Iterator[Route]:
    """Serpenoid routes first for N-link snakes, then one-harmonic periodic ones, for a
    nominal loop count and its doublings."""
    kinds = ["periodic"]
    if robot.kind == "snake" and robot.n_joints > 2:
        kinds.insert(0, "serpenoid")
    nominal = loop_counts(robot, target, MAX_STEPS)[0]
    for kind in kinds:
        for k in [nominal * 2**i for i in range(COUNTS)]:
            per_wave = max(1, k // 2) if kind == "serpenoid" else k
            if per_wave * MIN_LOOP_STEPS > MAX_STEPS:
                break  # more loops than one segment steps through
            x = fit_route(
                robot, start, target, kind, per_wave, _guesses(robot, start, kind), accuracy
            )
            if x is not None:
                yield Route.fitted(robot, start, kind, per_wave, x)


def _table_routes(
    robot: Robot, start: np.ndarray, target: np.ndarray, tol: Tolerance, capacity: int
) -> Iterator[Route]:
    """The table planner's routes (two harmonics: no on-board generator) as table loops,
    as many as a table plan for ``capacity`` would have."""
    for route in routes(robot, start, target, tol, capacity=capacity):
        loop = route.loop
        wave = Wave(
            loop.hub, loop.coefficients, route.count, None, robot.angles_to_ticks(loop.angles())
        )
        yield Route("table", start, (wave,))


def _realise(
    robot: Robot, target: np.ndarray, tol: Tolerance, route: Route, capacity: int
) -> ProgramPlan | None:
    """The route as a program; while its goals (as the controller rounds them) end
    outside the tolerance, the route is made again for a target moved by the error: a
    fitted one fitted again, a table loop's ticks nudged (``refine_ticks``)."""
    accuracy = solve_accuracy(robot, tol)
    aim = target
    best: ProgramPlan | None = None
    x: np.ndarray | None = None
    for attempt in range(CORRECTIONS + 1):
        try:
            program = build_program(robot, route)
        except (ProgramError, PlanError):
            return best
        reached = end_pose(robot, program)
        plan = ProgramPlan(robot, target, tol, program, route, reached, capacity)
        if best is None or plan.error[0] / tol.position < best.error[0] / tol.position:
            best = plan
        if plan.within or attempt == CORRECTIONS:
            break
        aim = se2.compose(aim, se2.relative(reached, target))
        wave = route.waves[0]
        if wave.ticks is not None:
            wanted = loop_target(robot, route.start, wave.hub, aim, wave.count)
            ticks, _ = refine_ticks(robot, wave.ticks, wanted, body_length(robot), accuracy)
            route = replace(route, waves=(replace(wave, ticks=ticks),))
            continue
        x = _parameters(route) if x is None else x
        x = fit_route(robot, route.start, aim, route.kind, wave.count, [x], accuracy)
        if x is None:
            break
        route = Route.fitted(robot, route.start, route.kind, wave.count, x)
    return best


def _parameters(route: Route) -> np.ndarray:
    """The fit's parameters of a fitted route (the inverse of ``Route.fitted``)."""
    first = route.waves[0]
    if first.serpenoid is None:
        return np.r_[first.hub, np.ravel(first.coefficients)]
    amplitude, delta = first.serpenoid
    shift = amplitude * np.sin(np.arange(len(first.hub)) * delta)
    offsets = [float(np.mean(w.hub - shift - route.start)) for w in route.waves]
    return np.array([amplitude, delta, *offsets])


def plan_program(request: PlanRequest) -> ProgramPlan:
    """A program of at most the request's capacity in bytes taking the robot where
    ``request`` asks, whose goals, as the controller sends them, end within the
    tolerance; Unreachable otherwise."""
    robot, capacity = request.robot, request.capacity
    goal, phi0, tol = request.checked()
    best: ProgramPlan | None = None
    too_big = 0
    accuracy = solve_accuracy(robot, tol)
    candidates = itertools.chain(
        _fitted_routes(robot, phi0, goal, accuracy),
        _table_routes(robot, phi0, goal, tol, capacity),
    )
    for route in candidates:
        plan = _realise(robot, goal, tol, route, capacity)
        if plan is None:
            continue
        size = len(plan.program.encode())
        if size > capacity:
            too_big = size if not too_big else min(too_big, size)
            continue
        if best is None or plan.error[0] / tol.position < best.error[0] / tol.position:
            best = plan
        if plan.within:
            return plan
    if best is None and too_big:
        raise out_of_reach(
            f"every program made for {robot.name} takes {too_big} bytes or more, more than "
            f"{capacity_words(capacity)} holds",
            capacity,
            "choose a nearer target",
            params=("target",),
        )
    if best is None:
        raise out_of_reach(
            f"no program for {robot.name} reaches x = {goal[0]:.4g}, y = {goal[1]:.4g}, "
            f"theta = {math.degrees(goal[2]):.1f} deg inside its joint limits (with "
            f"{LIMIT_MARGIN} rad to spare) and servo speed within {capacity_words(capacity)}",
            capacity,
            "choose a nearer target",
            "write a gait table instead of a program",
            params=("target", "output"),
        )
    d, h = best.error
    raise out_of_reach(
        f"the best program for {robot.name} ends {d:.3g} from the target and "
        f"{math.degrees(h):.2f} deg off its heading once its goals are rounded as the "
        f"controller rounds them, outside the tolerance ({tol.position:.3g}, "
        f"{math.degrees(tol.heading):.2f} deg)",
        capacity,
        "loosen the tolerance",
        "write a gait table instead of a program",
        params=("tolerance", "output"),
    )


__all__ = ["ProgramPlan", "Route", "Wave", "plan_program"]
