"""Shared by the physics world's tests: the gait they play."""

from __future__ import annotations

import math
from pathlib import Path

from snakebot.formats.gaittable import GaitTable, write_gait
from snakebot.model.gait import serpenoid
from snakebot.model.robots import load_robot


def snake5_serpenoid() -> GaitTable:
    """snake5's serpenoid: A = 30 deg, omega = pi, delta = pi/2, one 2 s cycle at 50 Hz."""
    robot = load_robot("snake5")
    gait = serpenoid(robot, math.radians(30), math.pi, math.pi / 2, cycles=1, rate_hz=50)
    return gait.gait_table()


def snake5_serpenoid_file(directory: Path) -> Path:
    """The same table written as DIRECTORY/s5.gait (with its metadata)."""
    path = directory / "s5.gait"
    write_gait(path, snake5_serpenoid())
    return path
