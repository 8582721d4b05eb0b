"""Choosing a world by name: ``kinematic`` (the minimum-slip model, ``snakebot.sim.world``;
with modelled servos, turned under the body's load, ``snakebot.sim.physics.joints``) or
``mujoco`` (this package). MuJoCo is imported only when its world is asked for."""

from __future__ import annotations

from typing import Any

from snakebot.errors import quoted
from snakebot.extras import require
from snakebot.model.robots import Robot
from snakebot.sim.bus.bus import Bus
from snakebot.sim.errors import SimOptionError
from snakebot.sim.world import World, WorldRecord

WORLDS = ("kinematic", "mujoco")
DEFAULT_WORLD = "kinematic"


def check_world(name: str) -> str:
    """``name`` if it is a world, else an error listing the worlds."""
    if name not in WORLDS:
        raise SimOptionError(f"unknown world {quoted(name)}: use {' or '.join(WORLDS)}")
    return name


def require_world(name: str) -> str:
    """``name`` if it is a world this installation can run (MuJoCo's needs the ``physics``
    extra), else an error saying what to install: for a command to check before it works."""
    if check_world(name) == "mujoco":
        require("mujoco", "the mujoco world")
    return name


def make_world(
    name: str,
    bus: Bus,
    robot: Robot,
    *,
    period: float,
    start: float | None = None,
    batch: int | None = None,
    mu: float | None = None,
    keep: int | None = None,
) -> Any:
    """A world of kind ``name`` on ``bus`` sampling every ``period`` from ``start``.
    ``batch`` tunes the kinematic world, ``mu`` the physics one (each ignores the
    other's); ``keep`` bounds the samples either keeps."""
    if check_world(name) == "kinematic":
        from snakebot.sim.physics.joints import LoadedWorld, loads_its_servos

        extra = {} if batch is None else {"batch": batch}
        kind = LoadedWorld if loads_its_servos(bus, robot) else World
        return kind(bus, robot, period=period, start=start, keep=keep, **extra)
    require("mujoco", "the mujoco world")
    from snakebot.sim.physics.world import PhysicsWorld

    return PhysicsWorld(bus, robot, period=period, start=start, mu=mu, keep=keep)


def world_of(record: WorldRecord) -> str:
    """The name of the world that made ``record``."""
    from snakebot.sim.physics.world import PhysicsRecord

    return "mujoco" if isinstance(record, PhysicsRecord) else "kinematic"


def record_extras(record: WorldRecord) -> dict[str, Any]:
    """What a physics record adds to a report's ``emulated`` part (nothing for the
    kinematic world)."""
    summary = getattr(record, "physics_summary", None)
    return summary() if summary is not None else {}
