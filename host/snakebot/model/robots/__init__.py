"""Robot descriptions: built-in ``snake3``, ``trident`` and ``snake5``, or a user's TOML file.

robot = load_robot("snake5")         # a built-in, by name
robot = load_robot("my_robot.toml")  # or a file (see the built-ins for the schema)
robot.angles_to_ticks(phi)           # joint angles (rad) -> AX-12 ticks

Calibrating a real robot's joints over a bus is :mod:`snakebot.link.bus.calibrate`.

May import: as the ``model`` layer (``formats``, ``facts``, the package root).
"""

from __future__ import annotations

from snakebot.model.robots.loader import BUILTIN_ROBOTS, load_robot, parse_robot
from snakebot.model.robots.model import (
    SERVO_MAX_RPM,
    SPEED_LIMITS,
    TICKS_PER_RAD,
    Friction,
    Joint,
    Physics,
    Robot,
    RobotError,
)

__all__ = [
    "BUILTIN_ROBOTS",
    "SERVO_MAX_RPM",
    "SPEED_LIMITS",
    "TICKS_PER_RAD",
    "Friction",
    "Joint",
    "Physics",
    "Robot",
    "RobotError",
    "load_robot",
    "parse_robot",
]
