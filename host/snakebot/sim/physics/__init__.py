"""The physics world: the robot in MuJoCo (mass, inertia, wheels that can slip, AX-12
actuators that run out of torque), beside the kinematic world of ``snakebot.sim.world``.

    world = PhysicsWorld(bus, robot)   # the same interface as World
    make_world("mujoco", bus, robot)   # either world by name

May import: as the ``sim`` layer (``sim.bus``, ``sim.servo``, ``sim.world``, the layers
below).
"""

from __future__ import annotations

from snakebot.sim.physics.actuator import Actuator
from snakebot.sim.physics.mjcf import build_mjcf
from snakebot.sim.physics.select import WORLDS, check_world, make_world
from snakebot.sim.physics.world import PhysicsError, PhysicsRecord, PhysicsWorld

__all__ = [
    "WORLDS",
    "Actuator",
    "PhysicsError",
    "PhysicsRecord",
    "PhysicsWorld",
    "build_mjcf",
    "check_world",
    "make_world",
]
