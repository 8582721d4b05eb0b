"""Serpenoid gaits: phi_k(t) = A sin(omega t + (k - 1) delta + phase) + phi_0 on every joint.

The frames sample the gait every frame period. omega is adjusted (by less than half a
frame over the whole gait) so the gait spans a whole number of frames: a whole number of
cycles then loops seamlessly, the last frame one period before the first repeats."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from snakebot.model.gait.common import (
    PREDICT_OPTIONS,
    Gait,
    GaitError,
    frame_budget,
    motion,
    path,
    period_ms_for,
    predict_table,
    singularity_warnings,
)
from snakebot.model.gait.limits import check_serpenoid, check_ticks
from snakebot.model.kinematics import Sines, integrate_joints
from snakebot.model.robots import Robot


@dataclass(frozen=True)
class SerpenoidWave:
    """A serpenoid gait as asked: phi_k(t) = ``amplitude`` sin(``omega`` t + (k - 1)
    ``delta`` + ``phase``) + ``offset`` (rad, rad/s) for ``cycles`` cycles, sampled at
    ``rate_hz``; ``loop``: whether the table repeats (default: when the cycles are whole)."""

    amplitude: float
    omega: float
    delta: float
    offset: float = 0.0
    phase: float = 0.0
    cycles: float = 1.0
    rate_hz: float = 50.0
    loop: bool | None = None


@dataclass(frozen=True)
class SerpenoidFrames:
    """A serpenoid gait's table, checked against the robot's limits, before any body
    motion is predicted (what a search needs of every candidate)."""

    ticks: np.ndarray  # (frames, joints)
    angles: np.ndarray  # the ticks' joint angles (rad): the table as the controller plays it
    period_ms: int
    loop: bool
    omega_used: float
    schedule: Sines
    steps: int

    @property
    def duration_s(self) -> float:
        return self.steps * self.period_ms / 1000.0


def serpenoid_frames(robot: Robot, wave: SerpenoidWave) -> SerpenoidFrames:
    """The frames of ``wave`` for ``robot``, checked against the robot's limits (GaitError,
    GaitLimitError otherwise)."""
    amplitude, omega, delta = wave.amplitude, wave.omega, wave.delta
    offset, phase, cycles, loop = wave.offset, wave.phase, wave.cycles, wave.loop
    if robot.kind != "snake":
        other = (
            "use `snakebot gait field` for it"
            if robot.kind == "trident"
            else f"its control fields are in `snakebot model fields {robot.name}`"
        )
        raise GaitError(
            f"{robot.name} is a {robot.kind}: the serpenoid gait drives a chain of links; " + other
        )
    for name, value in (
        ("amplitude", amplitude),
        ("omega", omega),
        ("delta", delta),
        ("offset", offset),
        ("phase", phase),
        ("cycles", cycles),
    ):
        if not math.isfinite(value):
            raise GaitError(f"the {name} must be a finite number, not {value}").about(name)
    if amplitude <= 0 or omega == 0 or cycles <= 0:
        raise GaitError("the amplitude and the cycles must be positive, and omega non-zero").about(
            "amplitude", "cycles", "omega"
        )
    period_ms = period_ms_for(wave.rate_hz)
    dt = period_ms / 1000.0
    whole = abs(cycles - round(cycles)) < 1e-9
    loop = whole if loop is None else loop
    if loop and not whole:
        raise GaitError(f"a looping table needs a whole number of cycles, not {cycles}")
    # Capped so that a tiny omega or a huge cycle count (an infinite quotient) reaches
    # the frame budget below as "too many frames" instead of failing to round.
    steps = round(min(cycles * 2 * math.pi / abs(omega) / dt, 2.0**53))
    if steps < 2:
        raise GaitError(
            "the gait is shorter than two frames: raise the rate or the cycles, or lower omega"
        ).about("rate", "cycles", "omega")
    frames = steps if loop else steps + 1
    frame_budget(
        robot, frames, "lower the rate or the cycles (or raise omega)", "rate", "cycles", "omega"
    )
    omega_used = math.copysign(2 * math.pi * cycles / (steps * dt), omega)
    schedule = Sines.serpenoid(robot.n_joints, amplitude, omega_used, delta, offset, phase)
    duration = steps * dt
    check_serpenoid(robot, amplitude, omega_used, schedule.phase, offset, duration, 16 * steps + 1)
    t_frames = np.arange(frames) * dt
    phi = amplitude * np.sin(omega_used * t_frames[:, None] + np.array(schedule.phase)) + offset
    ticks = robot.angles_to_ticks(phi)
    angles = robot.ticks_to_angles(ticks)
    check_ticks(robot, ticks, dt, loop, angles)

    return SerpenoidFrames(ticks, angles, period_ms, loop, omega_used, schedule, steps)


def serpenoid(
    robot: Robot,
    amplitude: float,
    omega: float,
    delta: float,
    *,
    offset: float = 0.0,
    phase: float = 0.0,
    cycles: float = 1.0,
    rate_hz: float = 50.0,
    loop: bool | None = None,
) -> Gait:
    """A serpenoid gait for a snake robot (checked against its limits): the wave
    :class:`SerpenoidWave` describes."""
    wave = SerpenoidWave(amplitude, omega, delta, offset, phase, cycles, rate_hz, loop)
    f = serpenoid_frames(robot, wave)
    dt = f.period_ms / 1000.0
    traj = integrate_joints(
        robot,
        f.schedule,
        f.duration_s,
        samples=min(8 * f.steps + 1, 4001),
        options=PREDICT_OPTIONS,
    )
    table_traj, note = predict_table(robot, f.ticks, dt, f.loop)
    parameters = {
        "amplitude_rad": amplitude,
        "omega_rad_s": f.omega_used,
        "omega_requested_rad_s": omega,
        "delta_rad": delta,
        "offset_rad": offset,
        "phase_rad": phase,
        "cycles": cycles,
        "rate_hz": 1000.0 / f.period_ms,
    }
    return Gait(
        robot,
        "serpenoid",
        parameters,
        f.period_ms,
        f.loop,
        f.ticks,
        motion(traj),
        {**motion(table_traj), **note},
        path(traj),
        path(table_traj),
        warnings=singularity_warnings({"continuous gait": traj, "table as written": table_traj}),
    )
