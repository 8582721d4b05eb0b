"""Closed loop for N-link snakes on a world that slips: whole serpenoid cycles, each at
one steering offset, planned as a car's path over a model of one cycle learned in the
world.

On MuJoCo the minimum-slip model's loops move snake5 nothing like the model says, but
its serpenoid behaves like a car, and read at the same phase of the wave it is a very
repeatable one (measured: ``docs/goto.md``):

- **the state is read once per cycle, at phase 0**: the pose the world reports (link 1's)
  and the joints' present positions read over the bus, as a real robot can. From both,
  the body's ``middle`` (the links' centroid and mean heading): link 1 alone turns
  against the body by twice a change of offset, the middle does not, and the servos lag
  behind a loaded body, so the shape sent is not the shape there is;
- **one cycle moves the middle along an arc** whose length shrinks with the offset and
  whose turn is linear in this cycle's offset and the last one's (the body takes about a
  cycle to bend to a new offset), the same curvature backwards; ``CycleModel`` fits
  that by least squares to every cycle played, drawn towards a prior from the geometry
  (an offset q at every joint curves the body by q per link);
- **each plan is whole cycles only** (a fraction of a cycle is what the model predicts
  worst): for the fewest cycles n, and each way of driving them (forwards, backwards,
  one reversal, two in short plans), the offsets are fitted so that link 1 ends at the
  target by the model, with the last cycle's shape; only the first cycle is played
  before the state is read and the rest of the plan fitted again (a new plan only when
  the rest no longer reaches the target), so the last cycles, planned from a state read
  one cycle before, carry only one cycle's model error;
- **a fraction of a cycle may end the run** (``finishing_fraction``): a whole cycle
  moves the body some 25 tolerances at the nearest targets, so near misses of two or
  three tolerances could only be corrected by a fresh manoeuvre of several cycles,
  which wandered tens of tolerances away and back (seed 36: 2.3x after cycle 11, 42x
  after 150). Before each cycle, if a fraction of one at the offset held ends link 1
  within the tolerance by the model, it is played instead; within twice the tolerance
  the run ends there, else the rest of that cycle takes the wave back to phase 0 and
  the loop goes on.

It meets twice the tolerance at most of the six test targets, some only after
wandering for many cycles (``docs/goto.md``).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snakebot.facts import devices
from snakebot.model.gait.limits import check_serpenoid
from snakebot.model.kinematics import Sines
from snakebot.model.plan import se2
from snakebot.model.plan.planner import (
    Tolerance,
    body_length,
    motion_dict,
    pose_dict,
    pose_error,
    ramp,
)
from snakebot.model.player import TICK_MS
from snakebot.model.robots import Robot

#: The wave: 30 degrees, 180 deg/s and a lag of 150 degrees between joints: a short wave
#: that carries snake5 0.105 m a cycle on MuJoCo and turns it 0.76 rad per cycle per
#: radian of offset, where ``snakebot drive``'s 90 degrees carries it 0.4 m and a plan's
#: last cycle could miss by centimetres.
AMPLITUDE = math.radians(30.0)
OMEGA = math.radians(180.0)
DELTA = math.radians(150.0)
#: Frames per cycle (the frame period is rounded to whole controller ticks).
FRAMES_PER_CYCLE = 100
#: The largest steering offset: with the amplitude the joints stay within 65 degrees of
#: straight; measured turning the body 0.46 rad per cycle (a radius of 0.16 m).
MAX_OFFSET = 0.6
#: The most the offset changes from one cycle to the next in a plan: larger changes
#: disturb the next cycles by more than the model says.
MAX_CHANGE = 0.3
#: The most cycles one plan may have, and the most cycles played.
HORIZON = 12
MAX_CYCLES = 150
#: Plans of up to this many cycles may reverse twice.
TWO_REVERSALS = 6
#: A new plan is taken when its end by the model is within this share of the tolerance;
#: the rest of the last plan, fitted again after a cycle, while it is within ``CONTINUE``
#: (its last cycles correct the rest: re-planning from scratch for each cycle's error,
#: about a tolerance, made the plans wander).
ACCEPT = 0.3
CONTINUE = 1.5
#: A fraction of a cycle at the offset held ends the run (``finish``) when the model
#: puts link 1 within this share of the tolerance after it.
FINISH_ACCEPT = 1.0
#: Weight of a change of offset (rad) against a miss of one tolerance in a plan's fit:
#: cycles after a change are the ones the model predicts worst.
SMOOTH = 0.5
#: Weight of the prior against one cycle's row in the model's fit, and the prior's
#: distance per straight cycle in body lengths (measured on MuJoCo; the cycles played
#: correct it).
PRIOR_WEIGHT = 0.5
PRIOR_DISTANCE = 0.15

_PRESENT = devices.ax12().register("Present Position")


@dataclass
class Wave:
    """The serpenoid being played: its phase, offset and the joints' angles now."""

    robot: Robot
    amplitude: float = AMPLITUDE
    omega: float = OMEGA
    delta: float = DELTA
    phase: float = 0.0
    offset: float = 0.0

    @property
    def period_ms(self) -> int:
        cycle_ms = 2000.0 * math.pi / self.omega
        return max(1, round(cycle_ms / FRAMES_PER_CYCLE / TICK_MS)) * TICK_MS

    def angles_at(self, phase: float, offset: float) -> np.ndarray:
        k = np.arange(self.robot.n_joints)
        return self.amplitude * np.sin(phase + k * self.delta) + offset

    def check(self) -> None:
        """The wave at the largest offsets, both ways, within the joints' limits and speed."""
        phases = Sines.serpenoid(
            self.robot.n_joints, self.amplitude, self.omega, self.delta, 0.0, 0.0
        ).phase
        for offset in (-MAX_OFFSET, MAX_OFFSET):
            check_serpenoid(
                self.robot,
                self.amplitude,
                self.omega,
                phases,
                offset,
                2 * math.pi / self.omega,
                4 * FRAMES_PER_CYCLE + 1,
                what="the closed loop's serpenoid",
                outcome="nothing was played",
            )

    def frames(self, offset: float, cycles: float) -> np.ndarray:
        """Joint frames for ``cycles`` (negative: backwards) at ``offset``, from where the
        wave is; the offset changes over the first quarter cycle. Advances the wave."""
        n = max(2, round(abs(cycles) * FRAMES_PER_CYCLE))
        steps = np.arange(n + 1)
        blend = np.clip(steps / (FRAMES_PER_CYCLE / 4), 0.0, 1.0)
        offsets = self.offset + (offset - self.offset) * blend
        phases = self.phase + math.copysign(2 * math.pi / FRAMES_PER_CYCLE, cycles) * steps
        out = np.array([self.angles_at(p, o) for p, o in zip(phases, offsets, strict=True)])
        self.phase, self.offset = float(phases[-1]), offset
        return out


def middle(robot: Robot, angles: np.ndarray) -> np.ndarray:
    """The body's middle frame (the links' centroid, their mean heading) in the frame
    of the pose the world reports (link 1's free end and heading)."""
    headings = np.r_[0.0, np.cumsum(angles)]
    ends = np.vstack(
        [np.zeros(2), np.cumsum(2 * robot.l * np.c_[np.cos(headings), np.sin(headings)], axis=0)]
    )
    centre = 0.5 * (ends[:-1] + ends[1:]).mean(axis=0)
    return np.r_[centre, headings.mean()]


def arc(turn: float, length: float) -> np.ndarray:
    """The pose change along a circular arc of signed ``length`` that turns by ``turn``."""
    if abs(turn) < 1e-9:
        return np.array([length, 0.0, turn])
    radius = length / turn
    return np.array([radius * math.sin(turn), radius * (1.0 - math.cos(turn)), turn])


@dataclass
class CycleModel:
    """One whole cycle's motion of the body's middle, learned: an arc of length
    ``d0 + d1 q^2 + d2 p^2 + d3 q p`` (as long backwards as forwards) turning by
    ``c0 + c1 q + c2 p`` (q the cycle's offset, p the last cycle's; negated backwards,
    where the path curves the same way); least squares over the cycles played, drawn
    towards ``prior`` (d0..d3, c0..c2)."""

    prior: np.ndarray
    rows: list[tuple[float, float, float, np.ndarray]] = field(default_factory=list)
    coefficients: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.prior = np.asarray(self.prior, dtype=float)
        self.coefficients = self.prior.copy()

    @classmethod
    def from_geometry(cls, robot: Robot, distance: float) -> CycleModel:
        """The prior for a wave that carries the body ``distance`` a straight cycle: an
        offset q at every joint curves it by q per link length, half of it at once."""
        turn = distance / (2 * robot.l)
        return cls(np.array([distance, 0.0, 0.0, 0.0, 0.0, 0.5 * turn, 0.5 * turn]))

    def length(self, q: float, p: float) -> float:
        d0, d1, d2, d3 = self.coefficients[:4]
        return d0 + d1 * q * q + d2 * p * p + d3 * q * p

    def turn(self, q: float, p: float) -> float:
        c0, c1, c2 = self.coefficients[4:]
        return c0 + c1 * q + c2 * p

    def motion(self, q: float, p: float, way: float) -> np.ndarray:
        """The middle's motion over one cycle at offset ``q`` after one at ``p``,
        forwards (``way`` 1) or backwards (-1)."""
        return arc(way * self.turn(q, p), way * self.length(q, p))

    def add(self, q: float, p: float, way: float, moved: np.ndarray) -> None:
        """One cycle's observed motion of the middle ``moved`` (in its frame at the start)."""
        self.rows.append((q, p, way, np.asarray(moved, dtype=float)))
        w = PRIOR_WEIGHT
        a_len, b_len = [w * np.eye(4)], [w * self.prior[:4]]
        a_turn, b_turn = [w * np.eye(3)], [w * self.prior[4:]]
        for q_, p_, way_, m in self.rows:
            turn = float(m[2])
            chord = float(np.hypot(m[0], m[1]))
            half = 0.5 * abs(turn)
            length = chord * half / math.sin(half) if half > 1e-9 else chord
            a_len.append(np.array([[1.0, q_ * q_, p_ * p_, q_ * p_]]))
            b_len.append(np.array([length]))
            a_turn.append(way_ * np.array([[1.0, q_, p_]]))
            b_turn.append(np.array([turn]))
        d = np.linalg.lstsq(np.vstack(a_len), np.concatenate(b_len), rcond=None)[0]
        c = np.linalg.lstsq(np.vstack(a_turn), np.concatenate(b_turn), rcond=None)[0]
        self.coefficients = np.r_[d, c]


@dataclass(frozen=True)
class Plan:
    """Whole cycles: each one's direction (1 forwards, -1 backwards) and offset, and
    how far from the target link 1 ends by the model, in tolerances."""

    ways: tuple[float, ...]
    offsets: tuple[float, ...]
    miss: float


def ways_of(n: int) -> list[tuple[float, ...]]:
    """The ways to drive ``n`` cycles: all forwards, all backwards, one reversal, and for
    short plans two (as a car parks: small corrections near the goal)."""
    out = [(1.0,) * n, (-1.0,) * n]
    for k in range(1, n):
        out += [(1.0,) * k + (-1.0,) * (n - k), (-1.0,) * k + (1.0,) * (n - k)]
    if n <= TWO_REVERSALS:
        for k in range(1, n):
            for m in range(k + 1, n):
                for way in (1.0, -1.0):
                    out.append((way,) * k + (-way,) * (m - k) + (way,) * (n - m))
    return out


def end_of(
    model: CycleModel,
    here: np.ndarray,
    offset: float,
    ways: tuple[float, ...],
    offsets: np.ndarray,
    link1: Any,
) -> tuple[float, float, float]:
    """Where link 1 ends by the model: the middle from ``here`` after the cycles, then
    link 1 from the middle with the shape ``link1(q)`` the last offset gives. (Plain
    floats: the planner calls this thousands of times a step.)"""
    coefficients = tuple(float(v) for v in model.coefficients)
    values = np.asarray(offsets, dtype=float).tolist()
    return _end(coefficients, tuple(float(v) for v in here), offset, ways, values, link1)


def _end(
    coefficients: tuple[float, ...],
    here: tuple[float, ...],
    offset: float,
    ways: tuple[float, ...],
    offsets: list[float],
    link1: Any,
) -> tuple[float, float, float]:
    """``end_of`` on plain floats throughout (a plan's fit converts the model and the
    state once, not at each of its thousands of calls)."""
    d0, d1, d2, d3, c0, c1, c2 = coefficients
    x, y, t = here
    p = offset
    for way, q in zip(ways, offsets, strict=True):
        length = way * (d0 + d1 * q * q + d2 * p * p + d3 * q * p)
        turn = way * (c0 + c1 * q + c2 * p)
        if abs(turn) < 1e-9:
            dx, dy = length, 0.0
        else:
            r = length / turn
            dx, dy = r * math.sin(turn), r * (1.0 - math.cos(turn))
        c, s = math.cos(t), math.sin(t)
        x, y, t = x + c * dx - s * dy, y + s * dx + c * dy, t + turn
        p = q
    lx, ly, lt = link1(p)
    c, s = math.cos(t), math.sin(t)
    return x + c * lx - s * ly, y + s * lx + c * ly, t + lt


def fit_offsets(
    ways: tuple[float, ...],
    x0: np.ndarray,
    goal: np.ndarray,
    tol: Tolerance,
    model: CycleModel,
    here: np.ndarray,
    offset: float,
    link1: Any,
    limit_changes: bool = True,
) -> Plan | None:
    """The offsets of the cycles driven ``ways`` that end link 1 nearest ``goal`` by the
    model (least squares from ``x0``, changes of offset kept small), from the middle at
    ``here`` and the offset now ``offset``; None when they break the limit on changes
    (unless ``limit_changes`` is false: then the changes are only kept small)."""
    from scipy.optimize import least_squares  # the planner's optional dependency

    coefficients = tuple(float(v) for v in model.coefficients)
    state = tuple(float(v) for v in here)

    def residual(x: np.ndarray) -> np.ndarray:
        # plain floats: the solver calls this thousands of times a plan
        values = x.tolist()
        ex, ey, et = _end(coefficients, state, offset, ways, values, link1)
        h = (et - goal[2] + math.pi) % (2 * math.pi) - math.pi
        changes = [b - a for a, b in zip([offset, *values[:-1]], values, strict=True)]
        return np.array(
            [
                (ex - goal[0]) / tol.position,
                (ey - goal[1]) / tol.position,
                h / tol.heading,
                *(10.0 * max(abs(c) - MAX_CHANGE, 0.0) for c in changes),
                *(SMOOTH * c for c in changes),
            ]
        )

    sol = least_squares(residual, x0, bounds=(-MAX_OFFSET, MAX_OFFSET))
    r = residual(sol.x)
    if limit_changes and np.any(r[3 : 3 + len(ways)] > 0.5):
        return None  # breaks the limit on changes of offset
    miss = float(np.hypot(np.hypot(r[0], r[1]), r[2]))
    return Plan(ways, tuple(float(v) for v in sol.x), miss)


def plan_cycles(
    model: CycleModel,
    here: np.ndarray,
    offset: float,
    goal: np.ndarray,
    tol: Tolerance,
    link1: Any,
    last: Plan | None = None,
) -> Plan:
    """The plan with the fewest whole cycles that ends link 1 within ``ACCEPT`` of the
    tolerance at ``goal`` by the model, from the middle at ``here`` and the offset now
    ``offset``; if none within ``HORIZON`` cycles does, the nearest one found. The rest
    of the ``last`` plan is tried first."""

    def fit(ways: tuple[float, ...], x0: np.ndarray) -> Plan | None:
        return fit_offsets(ways, x0, goal, tol, model, here, offset, link1)

    if last is not None and len(last.ways) > 1:
        # the rest of the last plan, fitted again from the state read: usually still good
        plan = fit(last.ways[1:], np.array(last.offsets[1:]))
        if plan is not None and plan.miss <= CONTINUE:
            return plan
    return fewest_cycles(fit, model, here, goal, 1, ACCEPT, ways_of)


def fewest_cycles(
    fit: Callable[[tuple[float, ...], np.ndarray], Plan | None],
    model: CycleModel,
    here: np.ndarray,
    goal: np.ndarray,
    least: int,
    accept: float,
    ways_for: Callable[[int], list[tuple[float, ...]]],
) -> Plan:
    """The plan of the fewest cycles, ``least`` or more (and no fewer than straight
    cycles of the model would take less one), up to ``HORIZON``, that ``fit`` ends
    within ``accept`` tolerances of ``goal`` driving one of ``ways_for(n)``, the
    smallest offsets among them; if none does, the nearest one found."""
    straight = model.length(0.0, 0.0)
    away = float(np.hypot(*se2.relative(here, goal)[:2]))
    # a model that has learned a straight cycle far shorter than the way left still
    # fits HORIZON cycles (the nearest it finds), never none
    near = math.floor(away / straight) - 1 if straight * HORIZON > away else HORIZON
    best = Plan((), (), math.inf)
    for n in range(max(1, least, near), HORIZON + 1):
        found = None
        for ways in ways_for(n):
            plan = fit(ways, np.zeros(n))
            if plan is None:
                continue
            if plan.miss < best.miss:
                best = plan
            if plan.miss <= accept and (
                found is None or sum(map(abs, plan.offsets)) < sum(map(abs, found.offsets))
            ):
                found = plan
        if found is not None:
            return found
    return best


def finishing_fraction(
    model: CycleModel,
    wave: Wave,
    here: np.ndarray,
    lag: np.ndarray,
    goal: np.ndarray,
    tol: Tolerance,
) -> tuple[float, float] | None:
    """The fraction of a cycle (signed: negative backwards), in whole frames, at the
    offset held that by the model ends link 1 nearest ``goal`` from the middle at
    ``here``, and that miss in tolerances (the larger of position and heading); None
    when no fraction ends within ``FINISH_ACCEPT``. The middle moves along the held
    offset's arc in proportion to the fraction; link 1 is placed from it by the wave's
    shape where the fraction leaves its phase, the servos lagging by ``lag``."""
    q = wave.offset
    turn, length = model.turn(q, q), model.length(q, q)
    best: tuple[float, float] | None = None
    for frames in range(2, FRAMES_PER_CYCLE - 1):  # the rest of the cycle is 2 frames or more
        for sign in (1.0, -1.0):
            f = sign * frames / FRAMES_PER_CYCLE
            phase = wave.phase + sign * 2 * math.pi / FRAMES_PER_CYCLE * frames
            shape = wave.angles_at(phase, q) + lag
            end = se2.compose(
                se2.compose(here, arc(f * turn, f * length)), se2.inverse(middle(wave.robot, shape))
            )
            d, h = pose_error(end, goal)
            miss = max(d / tol.position, abs(h) / tol.heading)
            if miss <= FINISH_ACCEPT and (best is None or miss < best[1]):
                best = (f, miss)
    return best


def present_angles(runner: Any) -> np.ndarray:
    """The joints' present positions, read over the bus (as the real robot's are)."""
    robot = runner.robot
    ticks = [runner.client.read_u16(sid, _PRESENT.address) for sid in robot.servo_ids]
    return robot.ticks_to_angles(np.array(ticks, dtype=float))


def link1_from_middle(wave: Wave, lag: np.ndarray) -> Any:
    """Link 1's pose in the middle's frame after a cycle at offset q, as a function of q:
    the wave's shape at phase 0 with the servos lagging by ``lag`` (as they lag now).
    Interpolated in a table: the planner calls it thousands of times a step."""
    grid = np.linspace(-MAX_OFFSET, MAX_OFFSET, 25)
    table = np.array([se2.inverse(middle(wave.robot, wave.angles_at(0.0, q) + lag)) for q in grid])
    return Interpolated(grid.tolist(), table.tolist())


@dataclass(frozen=True)
class Interpolated:
    """Rows of values at increasing ``grid`` points, linear in between and held beyond
    the ends (``np.interp``'s arithmetic, on plain floats: one call costs a
    microsecond where three ``np.interp`` calls cost ten)."""

    grid: list[float]
    rows: list[list[float]]

    def __call__(self, q: float) -> tuple[float, ...]:
        grid, rows = self.grid, self.rows
        if not q < grid[-1]:  # past the end, or NaN (which np.interp answers with NaN)
            return tuple(rows[-1]) if q == q else (math.nan,) * len(rows[-1])
        if q <= grid[0]:
            return tuple(rows[0])
        j = bisect.bisect_right(grid, q) - 1
        step = grid[j + 1] - grid[j]
        lo, hi = rows[j], rows[j + 1]
        return tuple((b - a) / step * (q - grid[j]) + a for a, b in zip(lo, hi, strict=True))


def follow(
    runner: Any,
    start: np.ndarray,
    goal: np.ndarray,
    tol: Tolerance,
    segments: list[dict[str, Any]],
    progress: Any,
) -> np.ndarray:
    """Drive the snake to ``goal`` with whole serpenoid cycles; the pose at the end.

    It stops within the tolerance, or within twice the tolerance when a plan has played
    out (a new plan costs cycles whose errors are about a tolerance each), or after
    ``MAX_CYCLES``."""
    robot = runner.robot
    wave = Wave(robot)
    wave.check()
    model = CycleModel.from_geometry(robot, PRIOR_DISTANCE * body_length(robot))
    plan = None
    to_wave = ramp(start, wave.angles_at(0.0, 0.0))
    pose = np.asarray(runner.play(to_wave, 0), dtype=float)
    segments.append({"kind": "to wave", "frames": len(to_wave) - 1, "pose": pose_dict(pose)})
    shape = present_angles(runner)
    here = se2.compose(pose, middle(robot, shape))
    for done in range(MAX_CYCLES):
        if progress is not None:
            progress(done + 1, MAX_CYCLES + 1)
        d, h = pose_error(pose, goal)
        if d <= tol.position and abs(h) <= tol.heading:
            break
        played_out = plan is not None and len(plan.ways) == 1
        if played_out and d <= 2 * tol.position and abs(h) <= 2 * tol.heading:
            break
        lag = shape - wave.angles_at(0.0, wave.offset)
        finish = finishing_fraction(model, wave, here, lag, goal, tol)
        if finish is not None:
            fraction, miss = finish
            before = pose
            pose = np.asarray(
                runner.play(wave.frames(wave.offset, fraction), wave.period_ms), dtype=float
            )
            segments.append(
                {
                    "kind": "finish",
                    "frames": round(abs(fraction) * FRAMES_PER_CYCLE),
                    "pose": pose_dict(pose),
                    "motion": motion_dict(se2.relative(before, pose)),
                    "offset_rad": wave.offset,
                    "cycles": fraction,
                    "planned_miss": miss,
                }
            )
            d, h = pose_error(pose, goal)
            if d <= 2 * tol.position and abs(h) <= 2 * tol.heading:
                break
            # missed: the rest of that cycle takes the wave back to phase 0, where the
            # state is read and planned from as before (not learned: it paused midway)
            rest = math.copysign(1.0 - abs(fraction), fraction)
            pose = np.asarray(
                runner.play(wave.frames(wave.offset, rest), wave.period_ms), dtype=float
            )
            shape = present_angles(runner)
            here = se2.compose(pose, middle(robot, shape))
            segments.append(
                {
                    "kind": "finish rest",
                    "frames": round(abs(rest) * FRAMES_PER_CYCLE),
                    "pose": pose_dict(pose),
                    "cycles": rest,
                }
            )
            plan = None
            continue
        link1 = link1_from_middle(wave, lag)
        plan = plan_cycles(model, here, wave.offset, goal, tol, link1, plan)
        way, q, p = plan.ways[0], plan.offsets[0], wave.offset
        before, was = pose, here
        pose = np.asarray(runner.play(wave.frames(q, way), wave.period_ms), dtype=float)
        shape = present_angles(runner)
        here = se2.compose(pose, middle(robot, shape))
        moved = se2.relative(was, here)
        predicted = model.motion(q, p, way)
        model.add(q, p, way, moved)
        segments.append(
            {
                "kind": "cycles",
                "frames": FRAMES_PER_CYCLE,
                "pose": pose_dict(pose),
                "motion": motion_dict(se2.relative(before, pose)),
                "offset_rad": q,
                "cycles": way,
                "planned_cycles": len(plan.ways),
                "joints_read": [float(v) for v in shape],
                "middle": {"planned": motion_dict(predicted), "observed": motion_dict(moved)},
            }
        )
    return pose
