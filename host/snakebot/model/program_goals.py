"""The host's prediction of a program's goals, in floating point (protocol/program.md,
"Goals"): what the controller's fixed-point stepping should send at every step, to
within one tick."""

from __future__ import annotations

import math

import numpy as np

from snakebot.core import ffi, lib
from snakebot.formats.program.layout import (
    JointRecord,
    PeriodicSegment,
    Program,
    Segment,
    SerpenoidSegment,
    TableSegment,
)
from snakebot.model.robots.model import TICKS_PER_RAD

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


def live_ticks(program: Program, schedule: list[tuple[int, int, int]]) -> np.ndarray:
    """goals[tick, joint] (whole ticks) the controller sends over a run of control ticks
    while the host changes Speed Scale and Steering Offset (protocol/program.md, "Live
    steering"): ``schedule`` gives per tick (dt ms since the last, the speed scale
    register, the steering register); the first tick starts the program (dt 0 there).

    The program's step is the scaled time's whole steps (``predict``'s goals for that
    step); the steering, added to the rounded goal as on the controller, is its slewed
    value, the target being the register while a serpenoid segment runs and 0 in the
    others; the slew is the controller's own (``play_slew_toward``, integer rules shared
    by the plain serpenoid), so what this checks is the generators under live changes."""
    goals = predict(program)
    starts = np.cumsum([0] + [s.steps for s in program.segments])
    low = np.array([j.low for j in program.joints])
    high = np.array([j.high for j in program.joints])
    sign = np.array([j.sign for j in program.joints])
    span = program.period_ms * 256
    slew = ffi.new("play_slew *")
    target = ffi.new("play_slew *")
    lib.play_slew_reset(slew)
    step, acc, running = 0, 0, True
    out = np.empty((len(schedule), len(program.joints)), dtype=np.int64)
    for row, (dt, scale, steering) in enumerate(schedule):
        if not running:  # the program has ended: its last goals stay
            out[row] = out[row - 1]
            continue
        segment = program.segments[int(np.searchsorted(starts, step, side="right")) - 1]
        serpenoid = isinstance(segment, SerpenoidSegment)
        target.amp_mrad = slew.amp_mrad = segment.amp_mrad if serpenoid else 0
        target.omega_mrad_s = slew.omega_mrad_s = segment.omega_mrad_s if serpenoid else 0
        target.phi0_mrad = 0
        target.steering = steering if serpenoid else 0
        target.speed_scale = scale
        lib.play_slew_toward(slew, target, dt)
        acc += dt * slew.speed_scale
        running = step + acc // span < program.total_steps
        step = min(step + acc // span, program.total_steps - 1)
        acc %= span
        out[row] = np.clip(np.rint(goals[step]) + sign * slew.steering, low, high)
    return out
