"""A table plan of whole serpenoid cycles for an N-link snake, made for a physics world.

The table planner's loops move snake5 by the small difference of larger motions, which
how the wheels share their slip decides: played open loop in MuJoCo they end tens to
hundreds of tolerances from where the quasi-static world puts them (``docs/goto.md``).
The serpenoid moves it like a car in both worlds, so a plan for MuJoCo drives whole
cycles of ``serpenoid_goto``'s wave instead: from the start the joints move to the wave,
play one cycle per steering offset forwards or backwards (``ways``), and move back to
the start. The lag between joints, ``delta``, is the same for the whole table and sets
how far a cycle carries the body (a few degrees of it change that by a few per cent), so
the offsets turn the body and ``delta`` sets the length of the way. Where such a table
ends is found by playing it in the world (``snakebot.workflows.plan_mujoco``); here is
the route, its table and the plan's report."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snakebot.formats.gaittable import table_size
from snakebot.model.gait.common import Gait, motion, motion_frame, path, table_motion
from snakebot.model.gait.limits import check_ticks
from snakebot.model.kinematics import Trajectory
from snakebot.model.plan.loops import PlanError
from snakebot.model.plan.planner import (
    EndsNearTarget,
    Tolerance,
    capacity_words,
    out_of_reach,
    pose_dict,
    ramp,
)
from snakebot.model.plan.serpenoid_goto import (
    DELTA,
    FRAMES_PER_CYCLE,
    CycleModel,
    Wave,
    fewest_cycles,
    fit_offsets,
    ways_of,
)
from snakebot.model.plan.serpenoid_goto import Plan as Cycles
from snakebot.model.robots import Robot

#: The most plays of a plan's tables in the world it is made for (in MuJoCo each about
#: 0.1 s of CPU a cycle).
MAX_PLAYS = 36
#: The most MuJoCo plays of a plan for both worlds (each with the quasi-static world's
#: plays, a few milliseconds each, for its Jacobian).
MAX_PLAYS_BOTH = 60
#: A route's largest miss by the car model, in tolerances, when it is chosen.
ROUTE_ACCEPT = 3.0
#: How far ``delta`` may move from the wave's own: the cycle's length changes by about a
#: third over it, and the wave stays a travelling one.
DELTA_RANGE = 0.35


def is_serpentine(robot: Robot) -> bool:
    """Whether the robot is an N-link snake, which a cycle plan drives (the trident and
    the 3-link snake have no serpenoid that carries them like a car)."""
    return robot.kind == "snake" and robot.n_joints > 2


def require_serpentine(robot: Robot, world: str) -> None:
    """A PlanError (about ``--world``) unless ``robot`` is an N-link snake: a plan for
    ``world`` drives serpenoid cycles."""
    if not is_serpentine(robot):
        raise PlanError(
            f"a plan for {world} drives serpenoid cycles, which {robot.name} has none of: "
            "plan it in the kinematic world"
        ).about("world")


def first_cycles(
    model: CycleModel,
    here: np.ndarray,
    goal: np.ndarray,
    tol: Tolerance,
    link1: Any,
    least: int = 1,
    reversals: int = 1,
) -> Cycles:
    """The fewest whole cycles, ``least`` or more (forwards, backwards, one reversal),
    that end link 1 within ``ROUTE_ACCEPT`` tolerances of ``goal`` by the car model
    (``serpenoid_goto``'s, from the middle at ``here``), the smallest offsets among
    them; the nearest of up to ``HORIZON`` cycles when none does. The model knows a
    cycle of one length only: the shooting sets the length by ``delta``, so fewer cycles
    that miss by a few tolerances are a better start than more that reach it by the
    model (more cycles, more of the world's differences to correct). When no cycles keep
    to ``serpenoid_goto``'s limit on changes of offset, they are fitted without it."""

    def ways_for(n: int) -> list[tuple[float, ...]]:
        return ways_of(n)[: 2 * n if reversals else 2]  # forwards, backwards, one reversal

    def fit_with(limit: bool) -> Callable[[tuple[float, ...], np.ndarray], Cycles | None]:
        return lambda ways, x0: fit_offsets(ways, x0, goal, tol, model, here, 0.0, link1, limit)

    found = fewest_cycles(fit_with(True), model, here, goal, least, ROUTE_ACCEPT, ways_for)
    if not found.ways:  # a table may change its offset faster than goto does
        found = fewest_cycles(fit_with(False), model, here, goal, least, ROUTE_ACCEPT, ways_for)
    return found


@dataclass(frozen=True)
class CycleRoute:
    """Whole cycles from ``start`` (joint angles): each one's direction (``ways``, 1
    forwards, -1 backwards) and steering offset (rad), at the lag ``delta``."""

    start: tuple[float, ...]
    ways: tuple[float, ...]
    offsets: tuple[float, ...]
    delta: float = DELTA

    def wave(self, robot: Robot) -> Wave:
        return Wave(robot, delta=self.delta)

    def angles(self, robot: Robot) -> np.ndarray:
        """The joint frames: the start, to the wave, the cycles, back to the start."""
        wave = self.wave(robot)
        start = np.asarray(self.start, dtype=float)
        rows = [ramp(start, wave.angles_at(0.0, 0.0))]
        for way, q in zip(self.ways, self.offsets, strict=True):
            rows.append(wave.frames(q, way)[1:])
        rows.append(ramp(rows[-1][-1], start)[1:])
        return np.vstack(rows)

    def cycle_frames(self, robot: Robot) -> list[int]:
        """The frame where each cycle begins, and the one where the last ends."""
        first = len(ramp(np.asarray(self.start), self.wave(robot).angles_at(0.0, 0.0))) - 1
        return [first + k * FRAMES_PER_CYCLE for k in range(len(self.ways) + 1)]

    @property
    def values(self) -> np.ndarray:
        """The offsets and the lag, as the solvers vary them (``with_values``)."""
        return np.r_[self.offsets, self.delta]

    def with_values(self, offsets: np.ndarray, delta: float) -> CycleRoute:
        return CycleRoute(self.start, self.ways, tuple(float(v) for v in offsets), float(delta))


def route_ticks(robot: Robot, route: CycleRoute, capacity: int) -> tuple[np.ndarray, int]:
    """The route's table in ticks and its frame period (ms), checked against the joints'
    limits and speed and against ``capacity`` (Unreachable when it does not fit)."""
    ticks = robot.angles_to_ticks(route.angles(robot))
    size = table_size(robot.n_joints, len(ticks))
    if size > capacity:
        raise out_of_reach(
            f"{len(route.ways)} serpenoid cycles take {size} bytes, more than "
            f"{capacity_words(capacity)}",
            capacity,
            "choose a nearer target",
            params=("target",),
        )
    period_ms = route.wave(robot).period_ms
    check_ticks(robot, ticks, period_ms / 1000.0, False)
    return ticks, period_ms


@dataclass
class CyclePlan(EndsNearTarget):
    """A cycle plan, its table (``gait``) and where it ends in the ``world`` it was
    played in (``reached``) after ``plays`` plays there."""

    robot: Robot
    target: np.ndarray
    tolerance: Tolerance
    route: CycleRoute
    gait: Gait
    reached: np.ndarray
    capacity: int
    world: str
    plays: int
    segments: list[dict[str, Any]] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        ticks = self.gait.ticks
        return {
            "robot": self.robot.name,
            "frame": motion_frame(self.robot),
            "world": self.world,
            "target": pose_dict(self.target),
            "predicted_final": pose_dict(self.reached),
            "error": self.tolerance.report(self.error),
            "start_rad": list(self.route.start),
            "route": "serpenoid cycles",
            "cycles": len(self.route.ways),
            "ways": list(self.route.ways),
            "offsets_rad": list(self.route.offsets),
            "delta_rad": self.route.delta,
            "plays": self.plays,
            "segments": self.segments,
            "frames": len(ticks),
            "table_bytes": table_size(self.robot.n_joints, len(ticks)),
            "capacity_bytes": self.capacity,
            "frame_period_ms": self.gait.period_ms,
            "duration_s": round(self.gait.duration_s, 6),
            "warnings": self.gait.warnings,
        }


def cycle_gait(robot: Robot, route: CycleRoute, ticks: np.ndarray, period_ms: int) -> Gait:
    """The route's table as a gait, with its motion in the quasi-static world (which the
    table's metadata and ``sim predict`` compare with)."""
    wave = route.wave(robot)
    played = table_motion(
        robot, robot.ticks_to_angles(ticks), period_ms / 1000.0, False, per_interval=2
    )
    traj: Trajectory = played.trajectory
    moved = motion(traj)
    return Gait(
        robot,
        "plan",
        {
            "route": "serpenoid cycles",
            "amplitude_rad": wave.amplitude,
            "omega_rad_s": wave.omega,
            "delta_rad": route.delta,
            "ways": list(route.ways),
            "offsets_rad": list(route.offsets),
            "rate_hz": 1000.0 / period_ms,
        },
        period_ms,
        False,
        ticks,
        moved,
        {**moved, **played.note()},
        path(traj),
        path(traj),
    )
