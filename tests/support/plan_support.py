"""The plan tests' targets and tolerance, shared by the planner's and the closed loop's
tests."""

from __future__ import annotations

import math

import numpy as np

from snakebot.model.plan import body_length
from snakebot.model.robots import load_robot

TOLERANCE = 0.02  # the issue's: 2 % of the distance
HEADING = math.radians(2.0)


def targets(robot_name, seed, count):
    """Seeded random targets between a quarter and one body length away, any direction,
    heading change up to 60 degrees."""
    rng = np.random.default_rng(seed)
    length = body_length(load_robot(robot_name))
    out = []
    for _ in range(count):
        bearing = rng.uniform(-math.pi, math.pi)
        distance = rng.uniform(0.25, 1.0) * length
        out.append(
            (distance * math.cos(bearing), distance * math.sin(bearing), rng.uniform(-1, 1) * 1.05)
        )
    return out


def within(reached, target):
    """The issue's tolerance, computed here from its words."""
    distance = math.hypot(target[0], target[1])
    d = math.hypot(reached[0] - target[0], reached[1] - target[1])
    h = (reached[2] - target[2] + math.pi) % (2 * math.pi) - math.pi
    return d <= TOLERANCE * distance and abs(h) <= HEADING, d, h
