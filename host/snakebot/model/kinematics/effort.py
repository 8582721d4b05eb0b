"""What a joint motion costs in the quasi-static world: the joints' torques, the work
they do against the wheels' friction, and whether the floor can give the links' inertia
the sideways force it needs (docs/models.md, "What the floor must supply").

The quasi-static model has no inertia: its friction forces balance by construction, each
within mu N. A real link also needs m a_n across its wheel to follow the predicted path;
``lateral_ratio`` is the largest |m a_n| / (mu N) over the wheels and samples. Above 1
the floor cannot give even the inertia alone and the wheel must slide where the model
has it roll. The quasi-static forces are not added in: where wheels slide the model's
forces sit on the friction limit whatever the motion, and where several wheels may stick
the split of force between them is not unique, so their sum with m a_n would flag gentle
gaits at random (a 10 deg serpenoid read 1.07 that way). The inertia alone scales with
the square of the speed, as it must (snake5's demo gait 0.56, at half speed 0.20).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from snakebot.model.kinematics.model import quasi_static_path
from snakebot.model.robots import Robot


@dataclass(frozen=True)
class Effort:
    """Per interval of a sampled joint motion: ``speed`` (rad/s) and ``torque`` (N m)
    of each joint at its middle; ``work_j`` the joints' signed mechanical work (J) in
    all; ``lateral_ratio`` as in the module's text."""

    speed: np.ndarray
    torque: np.ndarray
    work_j: float
    lateral_ratio: float


def effort(robot: Robot, q: np.ndarray, period_s: float) -> Effort:
    """The effort of the motion whose states ``q`` (rows x (3 + joints)) are sampled
    every ``period_s``, the joints taken linear between samples."""
    q = np.asarray(q, dtype=float)
    unit = 1.0 if robot.physics is None else robot.physics.unit_m
    mid = 0.5 * (q[1:] + q[:-1])
    speed = (q[1:, 3:] - q[:-1, 3:]) / period_s
    path = quasi_static_path(robot, mid, speed)
    torque = path.torque * unit
    pos = path.pos * unit
    count = len(mid)
    work = float(np.sum(torque * speed) * period_s)
    ratio = 0.0
    if count >= 3:
        acc = (pos[2:] - 2 * pos[1:-1] + pos[:-2]) / period_s**2
        t = path.dir[1:-1]
        a_n = acc[..., 1] * t[..., 0] - acc[..., 0] * t[..., 1]  # along the normal (-t_y, t_x)
        lat_max, _ = robot.wheel_friction_n()
        ratio = float((np.abs(robot.wheel_masses_kg() * a_n) / lat_max).max())
    return Effort(speed, torque, work, ratio)
