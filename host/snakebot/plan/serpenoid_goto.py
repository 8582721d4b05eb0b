"""Closed loop for N-link snakes on a world that slips: serpenoid cycles with a steering
offset, their distance and turn measured as they run.

On MuJoCo the minimum-slip model's loops move snake5 nothing like the model says, but
its serpenoid behaves like a car: one cycle carries the body about a wavelength along
(set by delta and the link length, hardly by the amplitude: 0.38 m for snake5),
backwards when omega is negative, and a steering offset phi0 curves its path by about
phi0 per link. The pose the world reports (link 1, the tail) swings with the wave
within a cycle and turns about a cycle after the offset changes; the body's middle
(``middle``: the links' centroid and mean heading, known from the joints) does
neither. So the closed loop here:

- **plays the serpenoid continuously**, segment by segment: each segment is a whole or
  fractional number of cycles at one offset (blended in over the first quarter cycle,
  the phase carried on), forwards or backwards; the pose is read after each;
- **learns the floor's response** (``CycleModel``): the middle's distance per cycle and
  its turn, linear in the offset, the cycles and the change of offset, fitted by least
  squares from a calibration (one straight cycle, one turning cycle) and every
  segment since;
- **plans a car's path** for the middle to where it must be for link 1 to end at the
  target: three arcs (turn, straight, turn; each forwards or backwards, offsets within
  ``MAX_OFFSET``), the shortest found that meets it by the learned model, and plays only
  the start of its first arc (at most ``MAX_STEP`` cycles, less near the goal) before
  planning again.

It does not yet meet the goal on MuJoCo (``docs/goto.md`` has the figures)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snakebot.gait.limits import check_serpenoid
from snakebot.kinematics import Sines
from snakebot.plan import se2
from snakebot.plan.planner import Tolerance, body_length, motion_dict, pose_dict, pose_error, ramp
from snakebot.robots import Robot
from snakebot.sim.controller_pty import TICK_MS

#: The wave: ``snakebot drive``'s defaults (30 degrees, 180 deg/s, 90 degrees).
AMPLITUDE = math.radians(30.0)
OMEGA = math.radians(180.0)
DELTA = math.radians(90.0)
#: Frames per cycle (the frame period is rounded to whole controller ticks).
FRAMES_PER_CYCLE = 100
#: The largest steering offset: with the amplitude it keeps the joints 30 degrees
#: inside +-90; larger offsets than about twice the amplitude stall the body on MuJoCo.
MAX_OFFSET = 0.3
#: The most of a cycle one segment plays before the pose is read and the path re-planned.
MAX_STEP = 0.5
#: The least a segment plays (shorter ones move the body less than the servos' lag).
MIN_STEP = 0.02
#: Segments at most, calibration included.
MAX_SEGMENTS = 40
#: The offset of the calibration's turning cycle.
CALIBRATION_OFFSET = 0.3
#: Weight of the seed (calibration) against the segments' rows in the model's fit,
#: and how much a row weighs against the next newer one.
PRIOR_WEIGHT, FORGET = 0.2, 0.9


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
    of the pose the world reports (link 1's free end and heading): the world's pose
    swings with the wave within a cycle, the middle hardly."""
    headings = np.r_[0.0, np.cumsum(angles)]
    ends = np.vstack(
        [np.zeros(2), np.cumsum(2 * robot.l * np.c_[np.cos(headings), np.sin(headings)], axis=0)]
    )
    centre = 0.5 * (ends[:-1] + ends[1:]).mean(axis=0)
    return np.r_[centre, headings.mean()]


@dataclass
class CycleModel:
    """What a segment does to the body's middle, learned: ``distance`` per cycle (as
    far back as forwards) and its turn, c0 + c1 phi0 per cycle plus c2 times the change
    of offset (which bends the body, and turns its middle, at once); least squares over
    the segments (recent ones weighing more) drawn towards a ``prior``."""

    distance: float
    prior: np.ndarray  # c0, c1, c2
    rows: list[tuple[np.ndarray, float]] = field(default_factory=list)
    lengths: list[tuple[float, float]] = field(default_factory=list)
    coefficients: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.coefficients = np.array(self.prior, dtype=float)

    def motion(self, offset: float, cycles: float, change: float) -> np.ndarray:
        """The middle's motion over ``cycles`` at ``offset`` after a ``change``."""
        c0, c1, c2 = self.coefficients
        kappa = (c0 + c1 * offset) / self.distance
        return se2.compose(np.array([0.0, 0.0, c2 * change]), arc(kappa, cycles * self.distance))

    def add(self, offset: float, cycles: float, change: float, moved: np.ndarray) -> None:
        """A segment's observed motion of the middle ``moved`` (body frame)."""
        self.lengths.append((abs(cycles), float(np.hypot(*moved[:2]))))
        self.rows.append((np.array([cycles, offset * cycles, change]), float(moved[2])))
        c, s = zip(*self.lengths, strict=True)
        self.distance = float(np.dot(c, s) / np.dot(c, c))
        a = [PRIOR_WEIGHT * np.eye(3)]
        b = [PRIOR_WEIGHT * self.prior]
        n = len(self.rows)
        for i, (x, y) in enumerate(self.rows):
            w = FORGET ** (n - 1 - i)
            a.append(w * x[None, :])
            b.append(np.array([w * y]))
        self.coefficients = np.linalg.lstsq(np.vstack(a), np.concatenate(b), rcond=None)[0]


def arc(kappa: float, length: float) -> np.ndarray:
    """The pose change along an arc of curvature ``kappa`` and signed ``length``."""
    turn = kappa * length
    if abs(turn) < 1e-9:
        return np.array([length, 0.5 * kappa * length**2, turn])
    return np.array([math.sin(turn) / kappa, (1.0 - math.cos(turn)) / kappa, turn])


def predict(model: CycleModel, offset: float, moves: np.ndarray) -> np.ndarray:
    """Where ``moves`` ((offset, cycles) rows) take the body's middle by the model, the
    offset ``offset`` now."""
    pose = np.zeros(3)
    for q, c in moves:
        pose = se2.compose(pose, model.motion(float(q), float(c), float(q) - offset))
        offset = float(q)
    return pose


#: Whether the closed loop drives backwards too (1) or forwards only (0).
BACKWARDS = 1
#: The most cycles one planned move may have.
MOST_CYCLES = 4.0


def plan_moves(model: CycleModel, offset: float, remaining: np.ndarray, scale: float) -> np.ndarray:
    """Three moves ((offset, cycles) rows; turn, straight, turn, each either way) that
    take the body to ``remaining`` by the model, the shortest found from a few starts."""
    from scipy.optimize import least_squares  # the planner's optional dependency

    lo = np.tile([-MAX_OFFSET, -MOST_CYCLES * BACKWARDS], 3)
    hi = np.tile([MAX_OFFSET, MOST_CYCLES], 3)

    def residual(x: np.ndarray) -> np.ndarray:
        end = predict(model, offset, x.reshape(-1, 2))
        h = (end[2] - remaining[2] + math.pi) % (2 * math.pi) - math.pi
        miss = np.r_[(end[:2] - remaining[:2]) / scale, h]
        return np.r_[miss, 0.02 * x[1::2]]

    best, best_cost = None, math.inf
    reach = float(np.hypot(*remaining[:2])) / model.distance
    for q1 in (-0.5 * MAX_OFFSET, 0.5 * MAX_OFFSET):
        for sign in (1.0, -1.0)[: 1 + BACKWARDS]:
            x0 = np.array([q1, 0.5 * sign, 0.0, sign * reach, -q1, 0.5 * sign])
            sol = least_squares(residual, np.clip(x0, lo, hi), bounds=(lo, hi))
            r = residual(sol.x)
            cost = 1e3 * float(np.sum(r[:3] ** 2)) + float(np.sum(np.abs(sol.x[1::2])))
            if cost < best_cost:
                best, best_cost = sol.x, cost
    assert best is not None
    return best.reshape(-1, 2)


def follow(
    runner: Any,
    start: np.ndarray,
    goal: np.ndarray,
    tol: Tolerance,
    segments: list[dict[str, Any]],
    progress: Any,
) -> np.ndarray:
    """Drive the snake to ``goal`` with serpenoid segments; the pose at the end."""
    robot = runner.robot
    scale = body_length(robot)
    wave = Wave(robot)
    wave.check()
    pose = np.zeros(3)
    centre = se2.compose(pose, middle(robot, start))
    steered: list[np.ndarray] = []
    total = MAX_SEGMENTS + 1
    done = 0

    def play(kind: str, angles: np.ndarray, period_ms: int, extra: dict[str, Any]) -> np.ndarray:
        nonlocal pose, done
        before = pose
        pose = np.asarray(runner.play(angles, period_ms), dtype=float)
        nonlocal centre
        was, centre = centre, se2.compose(pose, middle(robot, angles[-1]))
        moved = se2.relative(before, pose)
        steered.append(se2.relative(was, centre))
        segments.append({"kind": kind, "frames": len(angles) - 1, "pose": pose_dict(pose)})
        segments[-1]["motion"] = motion_dict(moved)
        segments[-1].update(extra)
        done += 1
        if progress is not None:
            progress(done, total)
        return moved

    def step(offset: float, count: float) -> None:
        """Play ``count`` cycles at ``offset`` and learn from what the middle did."""
        change = offset - wave.offset
        frames = wave.frames(offset, count)
        play("cycles", frames, wave.period_ms, {"offset_rad": offset, "cycles": count})
        model.add(offset, count, change, steered[-1])

    play("to wave", ramp(start, wave.angles_at(0.0, 0.0)), 0, {})
    # prior: a bend of phi0 at every joint curves the body by phi0 per link
    distance_guess = 0.5 * scale
    model = CycleModel(distance_guess, np.array([0.0, distance_guess / (2 * robot.l), 0.0]))
    # calibration, measured in the world itself: one straight cycle, one turning
    step(0.0, 1.0)
    step(CALIBRATION_OFFSET, 1.0)
    while done < total:
        d, h = pose_error(pose, goal)
        if d <= tol.position and abs(h) <= tol.heading:
            break
        # where the middle must be for link 1 to end at the goal, with the joints where
        # a segment ending now would leave them
        aim = se2.compose(goal, middle(robot, wave.angles_at(wave.phase, wave.offset)))
        remaining = se2.relative(centre, aim)
        moves = plan_moves(model, wave.offset, remaining, scale)
        offset, count = next(((q, c) for q, c in moves if abs(c) > MIN_STEP), moves[0])
        # segments shrink near the goal: at most the cycles the way left would take
        most = min(MAX_STEP, max(2 * MIN_STEP, float(np.hypot(*remaining[:2])) / model.distance))
        count = float(np.clip(count, -most, most))
        if abs(count) < MIN_STEP:
            count = math.copysign(MIN_STEP, count)
        step(float(offset), count)
    return pose
