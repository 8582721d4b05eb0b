"""The host's prediction of a program's goals, in floating point (protocol/program.md,
"Goals"): what the controller's fixed-point stepping should send at every step, to
within one tick."""

from __future__ import annotations

import math

import numpy as np

from snakebot.program.layout import (
    JointRecord,
    PeriodicSegment,
    Program,
    Segment,
    SerpenoidSegment,
    TableSegment,
)
from snakebot.robots.model import TICKS_PER_RAD

TICKS_PER_MRAD = TICKS_PER_RAD / 1000.0


def _goal(joint: JointRecord, angle_mrad: float) -> float:
    return joint.zero + joint.sign * angle_mrad * TICKS_PER_MRAD


def generate(program: Program, segment: Segment, step: int, k: int) -> float:
    """Joint k's goal (ticks, unrounded, without the carry) from a segment at a step."""
    joint = program.joints[k]
    t = step * program.period_ms / 1000.0  # seconds
    if isinstance(segment, TableSegment):
        return float(program.frames[segment.first + step % segment.count][k])
    if isinstance(segment, SerpenoidSegment):
        theta = segment.omega_mrad_s / 1000.0 * t + k * segment.delta_mrad / 1000.0
        return _goal(joint, segment.amp_mrad * math.sin(theta) + segment.phi0_mrad)
    assert isinstance(segment, PeriodicSegment)
    rate, a, b = program.blocks[segment.block][k]
    wt = segment.omega_mrad_s / 1000.0 * t
    return _goal(joint, rate * t + a * math.sin(wt) + b * math.cos(wt))


def predict(program: Program) -> np.ndarray:
    """goals[step, joint], unrounded ticks, for every step of the program in order: each
    segment's generator plus the carry that continues where the previous one would have
    gone next."""
    n = len(program.joints)
    out = np.empty((program.total_steps, n))
    carry = np.zeros(n)
    row = 0
    previous: Segment | None = None
    for segment in program.segments:
        for k in range(n):
            if previous is not None:
                end = generate(program, previous, previous.steps, k) + carry[k]
                carry[k] = end - generate(program, segment, 0, k)
        for step in range(segment.steps):
            out[row] = [generate(program, segment, step, k) + carry[k] for k in range(n)]
            row += 1
        previous = segment
    return out


def predicted_ticks(program: Program) -> np.ndarray:
    """The prediction rounded to whole ticks: goals[step, joint] as the servos get them."""
    return np.rint(predict(program)).astype(np.int64)
