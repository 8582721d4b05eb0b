"""What a joint motion costs in the quasi-static world: the joints' torques, the work
they do against the wheels' friction, and whether the floor can hold the wheels that the
model lets stick once the links' inertia is added (docs/models.md, "What the friction
must supply").

The quasi-static model has no inertia: a sticking wheel's lateral friction force is
whatever balances the others, at most mu N. A real link also needs m a to accelerate;
where |F + m a_n| exceeds mu N at a wheel the model lets stick, the real wheel slides and
the prediction is optimistic. ``lateral_ratio`` is the largest such ratio (1 or less:
the floor holds).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from snakebot.model.kinematics.model import quasi_static, wheels
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
    speed = np.diff(q[:, 3:], axis=0) / period_s
    count = len(mid)
    torque = np.empty((count, robot.n_joints))
    lateral = np.empty((count, robot.n_wheels))
    pos = np.empty((count, robot.n_wheels, 2))
    normal = np.empty((count, robot.n_wheels, 2))
    for k in range(count):
        qs = quasi_static(robot, mid[k], speed[k])
        torque[k] = qs.torque * unit
        lateral[k] = qs.lateral
        p, t = wheels(robot, mid[k])
        pos[k] = p * unit
        normal[k] = np.stack((-t[:, 1], t[:, 0]), axis=1)
    work = float(np.sum(torque * speed) * period_s)
    lat_max, _ = robot.wheel_friction_n()
    ratio = 0.0
    if count >= 3:
        acc = (pos[2:] - 2 * pos[1:-1] + pos[:-2]) / period_s**2
        a_n = np.einsum("kwi,kwi->kw", acc, normal[1:-1])
        force = lateral[1:-1]
        sticking = np.abs(force) < lat_max * (1 - 1e-9)
        need = np.abs(force + robot.wheel_masses_kg() * a_n) / lat_max
        ratio = float(need[sticking].max()) if sticking.any() else 0.0
    return Effort(speed, torque, work, ratio)
