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
from snakebot.model.gait.serpenoid import SerpenoidFrames, serpenoid_frames
from snakebot.model.kinematics import KinematicsError, Options, Table, integrate_joints
from snakebot.model.robots import Robot, load_robot
from snakebot.sim.world import SINGULAR_CODES, fallback_c_t
from snakebot.workflows.search.space import SearchError

METRICS = (
    "dx",
    "dy",
    "dtheta",
    "distance_per_cycle",
    "speed",
    "energy_j",
    "efficiency",
    "slip_per_cycle",
    "slip_ratio",
)
"""What a run reports: body motion over the run (robot length units, rad, in the start
pose's frame), distance per cycle, mean speed (units/s), the energy the motors put in
(J, physics only), distance per joule, the wheels' sideways slide per cycle (units) and
slide per distance travelled."""


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
    return serpenoid_frames(
        robot,
        point["amplitude"],
        point["omega"],
        point["delta"],
        offset=point["offset"],
        cycles=settings.cycles,
        rate_hz=settings.rate_hz,
    )


def _kinematic(robot: Robot, f: SerpenoidFrames, c_t: float) -> dict[str, float]:
    angles = robot.ticks_to_angles(f.ticks)
    period = f.period_ms / 1000.0
    schedule = Table(angles, period, f.loop)
    samples = f.steps + 1

    def run(c: float) -> Any:
        return integrate_joints(
            robot,
            schedule,
            f.duration_s,
            samples=samples,
            options=Options("rk4", h=period),
            c_t=c,
            with_slip=True,
        )

    try:
        traj = run(c_t)
    except KinematicsError as exc:
        fallback = fallback_c_t(robot, c_t)
        if fallback is None or exc.code not in SINGULAR_CODES:
            raise
        traj = run(fallback)
    speed = np.abs(traj.slip)
    slid = float(((speed[1:] + speed[:-1]) * 0.5 * period).sum())
    return motion(traj) | {"slip": slid, "energy_j": math.nan}


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
        record, _, _ = play(client, bus, robot, table, ideal=False, world="mujoco", mu=mu)
    finally:
        client.close()
    energy = getattr(record, "energy", None)
    return record.displacement() | {
        "slip": float(np.sum(record.slip_distance())),
        "energy_j": float(np.sum(energy)) if energy is not None else math.nan,
    }


def evaluate(settings: Settings, point: dict[str, float]) -> dict[str, Any]:
    """One run: ``point`` holds the serpenoid parameters and the robustness values (mu,
    mass, c_t); the row adds the status, the reason of a failure and METRICS (NaN if failed)."""
    row: dict[str, Any] = dict(point)
    row.update({m: math.nan for m in METRICS})
    try:
        robot = _robot(settings.robot)
        if "c_t" in point:
            robot = replace(robot, c_t=point["c_t"])
        if "mass" in point:
            robot = _heavier(robot, point["mass"])
        f = _frames(robot, settings, point)
        if settings.world == "kinematic":
            raw = _kinematic(robot, f, robot.c_t)
        else:
            raw = _physics(robot, f, point.get("mu"))
    except SnakebotError as exc:
        row.update(status="failed", reason=str(exc))
        return row
    distance = math.hypot(raw["dx"], raw["dy"])
    energy = raw["energy_j"]
    row.update(
        status="ok",
        reason="",
        dx=raw["dx"],
        dy=raw["dy"],
        dtheta=raw["dtheta"],
        distance_per_cycle=distance / settings.cycles,
        speed=distance / f.duration_s,
        energy_j=energy,
        efficiency=distance / energy if energy > 0 else math.nan,
        slip_per_cycle=raw["slip"] / settings.cycles,
        slip_ratio=raw["slip"] / distance if distance > 0 else math.inf,
    )
    return row


def evaluate_many(settings: Settings, points: list[dict[str, float]]) -> list[dict[str, Any]]:
    """Runs in one task (a worker call per run would cost more than a kinematic run)."""
    return [evaluate(settings, p) for p in points]
