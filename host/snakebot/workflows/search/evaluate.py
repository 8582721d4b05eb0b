"""One run of a search: a serpenoid candidate, limit-checked like ``gait serpenoid``,
played in one world, and the figures the objectives are made of.

The kinematic world integrates the table straight through the C core (ticks to angles,
linear in between, RK4 with one step per frame: the servos are ideal there, so the bus
would add nothing but time). The physics world plays the table on the emulated bus as
``sim predict --world mujoco`` does: the AX-12 registers drive the MuJoCo actuators.

A run that fails (the gait leaves the robot's limits, the integrator meets a singular
configuration, the physics blows up) is a row with status "failed" and the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np

from snakebot.errors import SnakebotError
from snakebot.formats.gaittable import GaitTable
from snakebot.model.gait.common import motion
from snakebot.model.gait.serpenoid import SerpenoidFrames, SerpenoidWave, serpenoid_frames
from snakebot.model.kinematics import Options, Table, integrate_joints
from snakebot.model.kinematics.effort import effort
from snakebot.model.robots import Robot, load_robot
from snakebot.sim.servo.motor import spec_for
from snakebot.workflows.search.space import SearchError

METRICS = (
    "dx",
    "dy",
    "dtheta",
    "distance_per_cycle",
    "speed",
    "work_j",
    "electrical_j",
    "efficiency",
    "slip_per_cycle",
    "slip_ratio",
    "torque_nm",
    "torque_ratio",
    "lateral_ratio",
)
"""What a run reports: body motion over the run (robot length units, rad, in the start
pose's frame), distance per cycle, mean speed (units/s), the joints' signed mechanical
work and the electrical energy the motors draw (J; DC motor model), distance per
electrical joule, the wheels' sideways slide per cycle (units) and slide per distance
travelled; in the kinematic world also the largest joint torque the motion needs
(N m), that over the torque the servos have, and the largest lateral force a sticking
wheel needs over what friction gives (model.kinematics.effort; above 1: the floor
cannot hold it)."""

FEASIBLE_LIMIT = 1.0
"""A candidate whose torque_ratio or lateral_ratio exceeds this is flagged infeasible."""


@dataclass(frozen=True)
class Settings:
    """What every run of a search shares."""

    robot: str  # a name or a .toml path, loaded once per worker process
    world: str
    cycles: float
    rate_hz: float


@lru_cache(maxsize=8)
def _robot(spec: str) -> Robot:
    return load_robot(spec)


def _frames(robot: Robot, settings: Settings, point: dict[str, float]) -> SerpenoidFrames:
    wave = SerpenoidWave(
        point["amplitude"],
        point["omega"],
        point["delta"],
        offset=point["offset"],
        cycles=settings.cycles,
        rate_hz=settings.rate_hz,
    )
    return serpenoid_frames(robot, wave)


def _kinematic(robot: Robot, f: SerpenoidFrames) -> dict[str, float]:
    period = f.period_ms / 1000.0
    traj = integrate_joints(
        robot,
        Table(f.angles, period, f.loop),
        f.duration_s,
        samples=f.steps + 1,
        options=Options("rk4", h=period),
        with_slip=True,
    )
    speed = np.abs(traj.slip)
    slid = float(((speed[1:] + speed[:-1]) * 0.5 * period).sum())
    cost = effort(robot, traj.q, period)
    spec = spec_for(robot.servo_model)
    electrical = float(np.sum(spec.electrical_power_w(cost.torque, cost.speed)) * period)
    limit = (robot.torque_limit_percent or 100.0) / 100.0
    peak = float(np.abs(cost.torque).max()) if cost.torque.size else 0.0
    return motion(traj) | {
        "slip": slid,
        "work_j": cost.work_j,
        "electrical_j": electrical,
        "torque_nm": peak,
        "torque_ratio": peak / (spec.stall_torque_nm * limit),
        "lateral_ratio": cost.lateral_ratio,
    }


def _heavier(robot: Robot, factor: float) -> Robot:
    """``robot`` with every link and wheel ``factor`` times as heavy (the physics world's
    body; the servos are the same)."""
    from snakebot.sim.physics.mjcf import physics_of

    if not factor > 0:
        raise SearchError(f"a mass factor must be positive, not {factor}")
    phys = physics_of(robot)
    return replace(
        robot,
        physics=replace(
            phys,
            link_mass_kg=phys.link_mass_kg * factor,
            wheel_mass_kg=phys.wheel_mass_kg * factor,
        ),
    )


def _physics(robot: Robot, f: SerpenoidFrames, mu: float | None) -> dict[str, float]:
    # imported here: the kinematic world needs neither MuJoCo nor the emulated bus
    from snakebot.link.transport import DxlClient
    from snakebot.workflows.predict import move_to_start, play, sim_url

    table = GaitTable(
        robot.servo_ids, f.period_ms, f.loop, robot.tick_limits, f.ticks.astype(np.uint16), {}
    )
    client = DxlClient(sim_url(robot, False), echo=False)
    try:
        bus = client.port.bus
        move_to_start(client, bus, robot, table.frames[0])
        record, *_ = play(client, bus, robot, table, ideal=False, world="mujoco", mu=mu)
    finally:
        client.close()
    summary = record.physics_summary() if hasattr(record, "physics_summary") else {}
    return record.displacement() | {
        "slip": float(np.sum(record.slip_distance())),
        "work_j": float(np.sum(summary.get("work_j", [math.nan]))),
        "electrical_j": float(np.sum(summary.get("electrical_j", [math.nan]))),
    }


def evaluate(settings: Settings, point: dict[str, float]) -> dict[str, Any]:
    """One run: ``point`` holds the serpenoid parameters and the robustness values (mu,
    mass, rolling); the row adds the status (``infeasible`` where a torque or lateral
    ratio exceeds FEASIBLE_LIMIT), the reason and METRICS (NaN if failed)."""
    row: dict[str, Any] = dict(point)
    row.update({m: math.nan for m in METRICS})
    try:
        robot = _robot(settings.robot)
        if "mu" in point or "rolling" in point:
            friction = replace(
                robot.friction,
                lateral=point.get("mu", robot.friction.lateral),
                rolling=point.get("rolling", robot.friction.rolling),
            )
            robot = replace(robot, friction=friction)
        if "mass" in point:
            robot = _heavier(robot, point["mass"])
        f = _frames(robot, settings, point)
        if settings.world == "kinematic":
            raw = _kinematic(robot, f)
        else:
            raw = _physics(robot, f, None)
    except SnakebotError as exc:
        row.update(status="failed", reason=str(exc))
        return row
    distance = math.hypot(raw["dx"], raw["dy"])
    energy = raw["electrical_j"]
    over = [
        f"{name} {raw[name]:.2f}"
        for name in ("torque_ratio", "lateral_ratio")
        if raw.get(name, 0.0) > FEASIBLE_LIMIT
    ]
    row.update({m: raw[m] for m in ("torque_nm", "torque_ratio", "lateral_ratio") if m in raw})
    row.update(
        status="infeasible" if over else "ok",
        reason=("needs more than the servos or the floor give: " + ", ".join(over) if over else ""),
        dx=raw["dx"],
        dy=raw["dy"],
        dtheta=raw["dtheta"],
        distance_per_cycle=distance / settings.cycles,
        speed=distance / f.duration_s,
        work_j=raw["work_j"],
        electrical_j=energy,
        efficiency=distance / energy if energy > 0 else math.nan,
        slip_per_cycle=raw["slip"] / settings.cycles,
        slip_ratio=raw["slip"] / distance if distance > 0 else math.inf,
    )
    return row


def evaluate_many(settings: Settings, points: list[dict[str, float]]) -> list[dict[str, Any]]:
    """Runs in one task (a worker call per run would cost more than a kinematic run)."""
    return [evaluate(settings, p) for p in points]
