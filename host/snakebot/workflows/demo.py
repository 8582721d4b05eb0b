"""The demo: the whole chain on the emulated 5-link robot, with the real firmware on an
emulated board (the CM-530's own image on the emulated STM32F103RE unless told otherwise).

1. Generate a serpenoid gait table for the robot (:func:`snakebot.model.gait.serpenoid`) and
   write it under ``out/``.
2. Start the emulated robot (:class:`snakebot.sim.serve.EmulatedRobot`): the firmware image
   on the emulated board (the CM-530, or QEMU), its Dynamixel bus on the emulated AX-12s,
   its PC link on a pseudo-terminal, and the world that moves the body from the servos' positions.
3. Upload the table over the PC link (:func:`snakebot.link.controller.upload.upload_gait`),
   play it in a loop (:func:`snakebot.link.controller.playback.play`) for a warm-up cycle and
   then the measured cycles, printing monitor lines, and stop it.
4. Compare: how far and in which direction the body went over the measured cycles, in the
   emulated world and as predicted from the table (:func:`compare`), and why they differ:
   the servos trail the commands (their lag). Write a PNG of both paths and of the joint
   angles, commanded beside measured.

Times: the comparison runs on the firmware's own timeline. The goals the firmware sent
(each servo's Goal Position, sampled with the world) say where in the table it was at
each instant, so the measured cycles are whole cycles of what it played (the emulated
board's clock may run a little slow on a loaded machine, so wall time alone would not
do). The body's motion per cycle depends on the joint path, not on how fast it is
played, so the prediction holds at any playback rate.

How the difference is explained (:class:`Comparison`): the measured joint angles are
fitted as the commanded ones delayed by ``lag`` (least squares over the measured cycles),
leaving a residual tracking error. The prediction for joints delayed by ``lag`` differs
from the plain prediction by ``lag_effect``; what the residual can add is bounded by its
largest value times the body's sensitivity to a joint-path error (displacement change per
radian of joint deviation, measured on the model with delayed joint paths), doubled for
safety. ``tolerance = lag_effect + 2 * sensitivity * residual``: the emulated result is
expected within it of the prediction.

The pace (:class:`Pacing`): on a busy host the emulator is descheduled, the firmware's goals stand
still and then leap ahead. Beyond the tolerance, a run whose pace was so disturbed is
INVALID rather than a disagreement: the host's scheduling may be what moved the robot.
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from snakebot.errors import RuntimeFailure
from snakebot.extras import install_hint
from snakebot.formats.gaittable import GaitTable, write_gait
from snakebot.link.controller import load as load_controller
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.errors import ControllerLinkError
from snakebot.link.controller.monitor import Sample, joint_of, render, sample
from snakebot.link.controller.playback import play, stop
from snakebot.link.controller.upload import UploadReport, upload_gait
from snakebot.model.compare import JointTrack, interp_rows, joint_names, motion, relative
from snakebot.model.gait import serpenoid
from snakebot.model.gait.common import motion_frame, table_motion
from snakebot.model.robots import Robot, load_robot
from snakebot.sim.physics.select import record_extras, world_of
from snakebot.sim.serve import DEFAULT_BOARD, EmulatedRobot, ServeInfo, check_firmware
from snakebot.sim.world import WorldRecord

FRAME_POLL_S = 0.1
"""Seconds between reads of the controller's Play Frame during playback."""

MONITOR_EVERY_S = 1.0
"""Seconds between the monitor lines printed during playback."""

LAG_SEARCH_S = (-0.05, 0.3)
"""Range of servo lags tried when fitting the measured joints to the commanded ones."""

LAG_STEP_S = 0.001

PHASE_SEARCH_FRAMES = (-0.5, 10.0)
"""Where the next sample's table position is looked for, relative to the last one."""

PHASE_STEP_FRAMES = 0.02

SENSITIVITY_DELAYS_S = (0.01, 0.02, 0.04)
"""Delays of the joint path used to measure the body's sensitivity to joint-path error."""

STALL_FACTOR = 3.0
"""Give up when playing takes this many times the table's nominal duration."""

RESIDUAL_SAFETY = 2.0
"""Factor on the residual-error term of the tolerance (see the module docstring)."""

STILL_LIMIT_S = 0.1
"""Longest the firmware's goals stand still in the measured cycles of a steady run. On a
quiet machine they move every 10-20 ms and stand still 20-100 ms at most; a host that
deschedules QEMU stops them for hundreds of milliseconds (see :class:`Pacing`)."""

LEAP_LIMIT_FRAMES = 2.0
"""Most table frames the goals advance between two samples (10 ms) in a steady run:
about half a frame, 2 at most on a quiet machine; after QEMU was descheduled 8-9 at
once, a chord the servos cut across the table's path."""

RATE_FLOOR = 0.7
"""Slowest a steady run plays, as a share of wall-clock speed (QEMU's clock lags the
wall's when it gets too little CPU): 0.84-0.94 on a quiet machine, 0.77-0.80 beside two
busy processes; beside four, 0.55-0.58, and the emulated robot strayed twice as far
from the prediction (2.9-3.2 cm against 1.2-2.0) with no stand-still or leap to show."""

SETTLE_S = 0.1
"""How long after a stand-still or a leap the servos' tracking is left out of the lag
fit (several times their lag)."""

MIN_STEADY_SAMPLES = 20
"""Fewer steady samples than this: the lag is measured on them all."""

PACING = {"qemu": " (QEMU does not pace the PC link at its baud rate)"}
"""What the upload's line adds on a board whose PC link is not paced at its baud rate
(the emulated STM32F103RE's USART3 is)."""

Say = Callable[[str], None]


class DemoError(RuntimeFailure):
    """The demo could not run to the end (the message says what went wrong and what to do)."""


@dataclass(frozen=True)
class DemoSettings:
    """What the demo plays. Angles in radians, omega in rad/s."""

    robot: str = "snake5"
    amplitude: float = math.radians(30.0)
    omega: float = math.pi  # a cycle every 2 s
    delta: float = math.radians(90.0)
    rate_hz: float = 50.0
    warmup_cycles: int = 1
    cycles: int = 5
    """Cycles measured: the table loops on the controller, so any number fits any board's
    table; more make a longer path to compare, 2 s each."""
    out_dir: Path = Path("out")
    firmware: Path | None = None
    board: str = DEFAULT_BOARD
    """The emulated board that runs the firmware (``cm530`` or ``qemu``)."""
    world: str = "mujoco"
    """The emulated world: "mujoco" (the physics, so the prediction is checked against
    something other than itself) or "kinematic" (the model the prediction uses)."""
    video: Path | None = None
    """Where to write a GIF/MP4 of the emulated robot (None: none)."""
    video_size: tuple[int, int] | None = None  # None: the video writer's default
    """The video's width and height in pixels."""


# -- the firmware's timeline --------------------------------------------------------------


def table_phase(
    angles: np.ndarray, goal_t: np.ndarray, goal_angles: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where in the looping table (fractional frames since PLAY, unwrapped) the firmware's
    goals were at each sample, from the first sample whose goals changed (PLAY) on: the
    nearest point of the table's path (linear between frames) a little ahead of the
    previous one. Returns (times, phases); phases never decrease."""
    changed = np.flatnonzero(np.abs(goal_angles - goal_angles[0]).max(axis=1) > 0)
    if not len(changed):
        raise DemoError(
            "the servos never got a goal from the firmware: is the robot's bus "
            "connected? (check `snakebot monitor`)"
        )
    begin = int(changed[0])
    steps = np.arange(PHASE_SEARCH_FRAMES[0], PHASE_SEARCH_FRAMES[1], PHASE_STEP_FRAMES)
    phases = np.empty(len(goal_t) - begin)
    p = 0.0
    for i, row in enumerate(goal_angles[begin:]):
        candidates = p + steps
        candidates = candidates[candidates >= 0]
        err = np.abs(commanded(angles, candidates) - row).max(axis=1)
        p = float(candidates[int(np.argmin(err))])
        phases[i] = p
    return goal_t[begin:], np.maximum.accumulate(phases)


def commanded(angles: np.ndarray, phase: np.ndarray) -> np.ndarray:
    """Joint angles of a looping table (rows = frames, radians) at fractional frame
    positions ``phase``: linear between frames, the last wrapping to the first."""
    n = len(angles)
    closed = np.vstack([angles, angles[:1]])
    p = np.mod(phase, n)
    k = np.minimum(np.floor(p).astype(int), n - 1)
    w = (p - k)[:, None]
    return closed[k] * (1 - w) + closed[k + 1] * w


# -- the comparison -----------------------------------------------------------------------


def predicted_motion(
    robot: Robot,
    angles: np.ndarray,
    period_s: float,
    cycles: int,
    delay_s: float = 0.0,
    samples: int = 2,
) -> np.ndarray:
    """Body poses (x, y, theta) over ``cycles`` whole cycles of the looping table, the joints
    delayed by ``delay_s``, from the origin (``gait.common.table_motion``, the prediction
    ``gait`` and ``sim predict`` make); at least ``samples`` rows evenly in time."""
    per_interval = max(1, math.ceil((samples - 1) / (cycles * len(angles))))
    played = table_motion(
        robot,
        angles,
        period_s,
        True,
        per_interval=per_interval,
        # the joints at window start are where the table was delay_s ago
        start_s=len(angles) * period_s - delay_s,
        passes=cycles,
    )
    return played.trajectory.q[:, :3]


#: The precision of each figure of :class:`Pacing`, in decimal places.
PACE_DIGITS = {"still_s": 3, "leap_frames": 2, "rate": 4}


@dataclass(frozen=True)
class Pacing:
    """How steadily the firmware's goals went through the table in the measured cycles,
    on the bus clock (wall time): the longest the goals stood still (s) and the most
    frames they advanced between two samples. The comparison assumes a steady pace: the
    servos then follow the table's path, late by their lag. A host that deschedules the
    emulator (or its threads) breaks that: the goals stop, the servos catch up and
    stop, then the goals leap ahead and the servos cut across the path. The servos' lag
    and tracking error, hence the tolerance, are measured on the steady stretches
    (:func:`steady_samples`); a difference beyond the tolerance may then be the host's
    doing rather than the prediction's (:attr:`Comparison.verdict`)."""

    still_s: float
    leap_frames: float
    rate: float = 1.0
    """How fast the firmware played, as a share of wall-clock speed."""

    def __post_init__(self) -> None:
        # judged on the figures the report shows (1 ms, 0.01 frame, 0.0001x), so that a
        # run is never called disturbed by a stand-still it reports as the limit itself
        for name, digits in PACE_DIGITS.items():
            object.__setattr__(self, name, round(float(getattr(self, name)), digits))

    @property
    def steady(self) -> bool:
        return (
            self.still_s <= STILL_LIMIT_S
            and self.leap_frames <= LEAP_LIMIT_FRAMES
            and self.rate >= RATE_FLOOR
        )

    def line(self) -> str:
        """The report's line on the pace."""
        seen = (
            f"the firmware's goals stood still {1000 * self.still_s:.0f} ms at most and "
            f"leapt {self.leap_frames:.1f} frames at most"
        )
        if self.steady:
            limits = f"{1000 * STILL_LIMIT_S:.0f} ms and {LEAP_LIMIT_FRAMES:g} frames"
            return (
                f"   pace: steady ({seen}, at {self.rate:.2f}x wall-clock speed; a steady "
                f"run stays within {limits}, at {RATE_FLOOR:g}x or more)."
            )
        return (
            f"   pace: disturbed by the host (the firmware's goals {self.problem()}); "
            "the servos' lag and tracking error are measured where it was steady."
        )

    def problem(self) -> str:
        """What went wrong with the pace, in words ("" when it was steady)."""
        found = []
        if self.still_s > STILL_LIMIT_S:
            found.append(
                f"stood still {1000 * self.still_s:.0f} ms (at most "
                f"{1000 * STILL_LIMIT_S:.0f} ms on a steady run)"
            )
        if self.leap_frames > LEAP_LIMIT_FRAMES:
            found.append(
                f"leapt {self.leap_frames:.1f} frames at once (at most "
                f"{LEAP_LIMIT_FRAMES:g} on a steady run)"
            )
        if self.rate < RATE_FLOOR:
            found.append(
                f"came at {self.rate:.2f}x wall-clock speed (at least {RATE_FLOOR:g}x on a "
                "steady run: the emulator got too little CPU)"
            )
        return " and ".join(found)

    def as_dict(self) -> dict[str, Any]:
        return {
            "steady": self.steady,
            "still_s": self.still_s,
            "leap_frames": self.leap_frames,
            "rate": self.rate,
            "still_limit_s": STILL_LIMIT_S,
            "leap_limit_frames": LEAP_LIMIT_FRAMES,
            "rate_floor": RATE_FLOOR,
        }


def pacing(
    phase_t: np.ndarray, phase: np.ndarray, t_a: float, t_b: float, rate: float = 1.0
) -> Pacing:
    """The pace of the firmware's goals between ``t_a`` and ``t_b`` (see :class:`Pacing`),
    from their table positions (``table_phase``); ``rate``: its playback rate."""
    inside = (phase_t >= t_a) & (phase_t <= t_b)
    t, p = phase_t[inside], phase[inside]
    if len(t) < 2:
        return Pacing(still_s=t_b - t_a, leap_frames=0.0, rate=rate)
    step = np.diff(p)
    moved = t[1:][step > 0]  # the sample times at which the goals had moved on
    still = float(np.diff(np.concatenate([[t_a], moved, [t_b]])).max())
    return Pacing(still_s=still, leap_frames=float(step.max()), rate=rate)


def steady_samples(t: np.ndarray, phase_t: np.ndarray, phase: np.ndarray) -> np.ndarray:
    """Which of the times ``t`` the servos were following a steady pace: not while the
    firmware's goals stood still longer than ``STILL_LIMIT_S`` or leapt more than
    ``LEAP_LIMIT_FRAMES`` at once, nor for ``SETTLE_S`` after."""
    step = np.diff(phase)
    moved = phase_t[1:][step > 0]
    spans = [(a, b) for a, b in zip(moved[:-1], moved[1:], strict=True) if b - a > STILL_LIMIT_S]
    spans += [(phase_t[k], phase_t[k + 1]) for k in np.flatnonzero(step > LEAP_LIMIT_FRAMES)]
    disturbed = np.zeros(len(t), dtype=bool)
    for a, b in spans:
        disturbed |= (t >= a) & (t <= b + SETTLE_S)
    return ~disturbed


@dataclass
class Comparison:
    """The emulated body's motion over the measured cycles beside the prediction."""

    emulated: dict[str, float]
    predicted: dict[str, float]
    difference_m: float
    lag_s: float
    residual_max_rad: float
    lag_effect_m: float
    sensitivity_m_per_rad: float
    tolerance_m: float
    playback_rate: float
    window_s: tuple[float, float]
    emulated_path: np.ndarray = field(repr=False)
    predicted_path: np.ndarray = field(repr=False)
    joints: JointTrack = field(repr=False)  # measured by the servos, commanded by the firmware
    predicted_lagged: dict[str, float] = field(default_factory=dict)
    """The prediction for joints that trail the table by the measured ``lag_s``."""
    physics: dict[str, Any] | None = None
    """With the physics world: what it adds (see :func:`physics_effects`)."""
    free_wheel_path: np.ndarray | None = field(default=None, repr=False)
    """With the physics world: the path predicted for free-rolling wheels."""
    pace: Pacing = field(default_factory=lambda: Pacing(0.0, 0.0))
    """How steadily the firmware played the measured cycles."""

    @property
    def within_tolerance(self) -> bool:
        return self.difference_m <= self.tolerance_m

    @property
    def verdict(self) -> str:
        """AGREE within the tolerance; beyond it DISAGREE, or INVALID when the host
        disturbed the firmware's pace, since the host's scheduling may then be what took
        the robot off the predicted path."""
        if self.within_tolerance:
            return "AGREE"
        return "DISAGREE" if self.pace.steady else "INVALID"

    @property
    def after_lag_m(self) -> float:
        """How far the emulated motion is from the prediction with the servos' lag in it:
        what the lag does not account for."""
        e, p = self.emulated, self.predicted_lagged
        return math.hypot(e["dx"] - p["dx"], e["dy"] - p["dy"])

    @property
    def lag_part_m(self) -> float:
        """How much of the difference the servos' measured lag accounts for: how much
        closer the prediction comes with the lag in it (0 if it comes no closer)."""
        return max(0.0, self.difference_m - self.after_lag_m)

    @property
    def cause(self) -> str:
        """The larger of the two measured parts of the difference: "servo lag" (the lag's
        part) or what is left after it: "physics" (the body's mass, the wheels' slide) in
        the physics world, "tracking error" (the servos' error beyond a plain delay) in
        the kinematic one."""
        if self.lag_part_m >= self.after_lag_m:
            return "servo lag"
        return "tracking error" if self.physics is None else "physics"

    def as_dict(self) -> dict[str, Any]:
        return {
            "verdict": self.verdict,
            "pacing": self.pace.as_dict(),
            "emulated": _rounded(self.emulated),
            "predicted": _rounded(self.predicted),
            "difference_m": round(self.difference_m, 6),
            "tolerance_m": round(self.tolerance_m, 6),
            "within_tolerance": self.within_tolerance,
            "reason": self.cause,
            "lag_part_m": round(self.lag_part_m, 6),
            "after_lag_m": round(self.after_lag_m, 6),
            "predicted_with_lag": _rounded(self.predicted_lagged),
            "servo_lag_ms": round(1000 * self.lag_s, 1),
            "tracking_error_deg": {
                "max": round(math.degrees(self.joints.max_rad), 3),
                "rms": round(math.degrees(self.joints.rms_rad), 3),
                "max_after_lag": round(math.degrees(self.residual_max_rad), 3),
            },
            "lag_effect_m": round(self.lag_effect_m, 6),
            "sensitivity_m_per_rad": round(self.sensitivity_m_per_rad, 6),
            "playback_rate": round(self.playback_rate, 4),
            "window_s": [round(self.window_s[0], 3), round(self.window_s[1], 3)],
            **({} if self.physics is None else {"physics": self.physics}),
        }


def _rounded(d: dict[str, float]) -> dict[str, float]:
    return {k: round(v, 6) for k, v in d.items()}


def compare(
    robot: Robot,
    table: GaitTable,
    record: WorldRecord,
    goal_t: np.ndarray,
    goal_ticks: np.ndarray,
    warmup_cycles: int,
    cycles: int,
) -> Comparison:
    """The body's motion over ``cycles`` cycles of the table after ``warmup_cycles`` (as the
    firmware's goals went through them), emulated (the world's record) beside predicted
    (the table, linear between frames), with the servo lag that explains the difference
    (see the module docstring). ``goal_t``, ``goal_ticks``: the goals the servos received,
    sampled at the world's sample times."""
    angles = robot.ticks_to_angles(table.frames.astype(float))
    frames = len(angles)
    period_s = table.frame_period_ms / 1000.0
    goal_angles = robot.ticks_to_angles(goal_ticks)
    phase_t, phase = table_phase(angles, goal_t, goal_angles)
    target_a, target_b = warmup_cycles * frames, (warmup_cycles + cycles) * frames
    if phase[-1] < target_b:
        raise DemoError(
            f"the firmware played {phase[-1] / frames:.2f} cycles, fewer than the "
            f"{warmup_cycles + cycles} asked for: play longer"
        )
    t_a = float(np.interp(target_a, phase, phase_t))
    t_b = float(np.interp(target_b, phase, phase_t))
    inside = (record.t >= t_a) & (record.t <= t_b)
    t = record.t[inside]
    measured = record.phi[inside]

    def cmd(delay: float) -> np.ndarray:  # the firmware's goals, ``delay`` seconds ago
        return np.column_stack(
            [np.interp(t - delay, goal_t, goal_angles[:, j]) for j in range(goal_angles.shape[1])]
        )

    plain = cmd(0.0)
    # the servos' lag and tracking error where the pace was steady: what the host's
    # stalls add is no property of the servos (the verdict weighs the pace apart)
    keep = steady_samples(t, phase_t, phase)
    if keep.sum() < MIN_STEADY_SAMPLES:
        keep = np.ones(len(t), dtype=bool)
    lags = np.arange(LAG_SEARCH_S[0], LAG_SEARCH_S[1] + LAG_STEP_S / 2, LAG_STEP_S)
    errors = [float(np.mean((measured - cmd(lag))[keep] ** 2)) for lag in lags]
    lag = float(lags[int(np.argmin(errors))])
    residual_max = float(np.abs(measured - cmd(lag))[keep].max())

    pose_a = interp_rows(np.array([t_a]), record.t, record.pose)[0]
    em_t = np.concatenate([[t_a], t, [t_b]])
    em_pose = relative(pose_a, interp_rows(em_t, record.t, record.pose))
    emulated = motion(em_pose[-1])

    # The table's own time runs at ``rate`` x world time (the board's clock may lag the wall).
    rate = (target_b - target_a) * period_s / (t_b - t_a)
    path = predicted_motion(robot, angles, period_s, cycles, samples=200 * cycles + 1)
    predicted = motion(path[-1])

    def delayed(delay_s: float) -> dict[str, float]:
        return motion(predicted_motion(robot, angles, period_s, cycles, delay_s * rate)[-1])

    def shift(delay_s: float) -> float:
        moved = delayed(delay_s)
        return math.hypot(moved["dx"] - predicted["dx"], moved["dy"] - predicted["dy"])

    lagged = delayed(lag)
    lag_effect = math.hypot(lagged["dx"] - predicted["dx"], lagged["dy"] - predicted["dy"])
    sensitivity = 0.0
    one_cycle = np.linspace(0.0, frames, 20 * frames, endpoint=False)
    for d in SENSITIVITY_DELAYS_S:
        deviation = float(
            np.abs(
                commanded(angles, one_cycle) - commanded(angles, one_cycle - d * rate / period_s)
            ).max()
        )
        if deviation > 0:
            sensitivity = max(sensitivity, shift(d) / deviation)
    return Comparison(
        emulated=emulated,
        predicted=predicted,
        predicted_lagged=lagged,
        difference_m=math.hypot(emulated["dx"] - predicted["dx"], emulated["dy"] - predicted["dy"]),
        lag_s=lag,
        residual_max_rad=residual_max,
        lag_effect_m=lag_effect,
        sensitivity_m_per_rad=sensitivity,
        tolerance_m=lag_effect + RESIDUAL_SAFETY * sensitivity * residual_max,
        playback_rate=rate,
        window_s=(t_a, t_b),
        emulated_path=em_pose,
        predicted_path=path,
        joints=JointTrack(t, joint_names(robot), measured, plain),
        pace=pacing(phase_t, phase, t_a, t_b, rate),
    )


def physics_effects(
    robot: Robot, table: GaitTable, record: WorldRecord, comparison: Comparison, cycles: int
) -> tuple[dict[str, Any], np.ndarray]:
    """What the physics world adds to the comparison: the prediction for free-rolling
    wheels (no rolling resistance or axle friction, where both worlds take the robot's),
    the wheels' sideways slide over the measured cycles (m), and each joint's work and
    electrical energy (J) and peak load over the whole run; and the free-wheel path
    (poses as the predicted path has them)."""
    angles = robot.ticks_to_angles(table.frames.astype(float))
    free_wheels = replace(robot, friction=replace(robot.friction, rolling=0.0, axle_nm=0.0))
    samples = len(comparison.predicted_path)
    free_path = predicted_motion(
        free_wheels, angles, table.frame_period_ms / 1000.0, cycles, samples=samples
    )
    free = motion(free_path[-1])
    e = comparison.emulated
    t_a, t_b = comparison.window_s
    inside = (record.t >= t_a) & (record.t <= t_b)
    slid = WorldRecord(
        record.t[inside],
        record.pose[inside],
        record.phi[inside],
        record.slip[inside],
        record.friction,
    ).slip_distance()
    extras = record_extras(record)
    return {
        "friction": asdict(robot.friction),
        "predicted_free_wheels": _rounded(free),
        "difference_free_wheels_m": round(
            math.hypot(e["dx"] - free["dx"], e["dy"] - free["dy"]), 6
        ),
        "wheel_slide_m": [round(float(v) * _unit(robot), 6) for v in slid],
        "work_j": [round(v, 6) for v in extras["work_j"]],
        "electrical_j": [round(v, 6) for v in extras["electrical_j"]],
        "peak_load": [round(v, 4) for v in extras["peak_load"]],
        "mu": extras["mu"],
    }, free_path


def _why(c: Comparison) -> str:
    """What the plot's title names as the cause of the difference: the servos' lag alone
    in the kinematic world; with physics, mostly what the physics adds (free-rolling
    wheels, slide), which the lag is small beside."""
    lag = f"servo lag {1000 * c.lag_s:.0f} ms"
    if c.physics is None:
        return lag
    free = 100 * c.physics["difference_free_wheels_m"]
    slide = 100 * sum(c.physics["wheel_slide_m"])
    return f"free-wheel prediction {free:.1f} cm off; wheels slid {slide:.1f} cm; {lag}"


def _unit(robot: Robot) -> float:
    return robot.physics.unit_m if robot.physics is not None else 1.0


# -- the operation ------------------------------------------------------------------------


@dataclass
class DemoResult:
    """Everything the demo did and measured."""

    settings: DemoSettings
    info: dict[str, Any]
    gait_file: Path
    gait: dict[str, Any]
    upload: UploadReport
    comparison: Comparison
    seconds: float
    monitor: list[dict[str, Any]]
    record: WorldRecord
    png: Path | None = None  # drawn by snakebot.plots.demo; None without matplotlib

    def as_dict(self) -> dict[str, Any]:
        return {
            "robot": self.settings.robot,
            "world": self.settings.world,
            "board": self.settings.board,
            "firmware": self.info["firmware"],
            "qemu_pid": self.info["qemu_pid"],
            "gait_file": str(self.gait_file),
            "gait": self.gait,
            "upload": self.upload.as_dict(),
            "cycles": {"warmup": self.settings.warmup_cycles, "measured": self.settings.cycles},
            **self.comparison.as_dict(),
            "png": None if self.png is None else str(self.png),
            **({"video": str(self.settings.video)} if self.settings.video else {}),
            "monitor": self.monitor,
            "seconds": round(self.seconds, 2),
        }


def _monitor_line(s: Sample) -> str:
    c = s.controller_record()
    servos = "  ".join(
        f"{j.id}:{math.degrees(joint_of(j).tick_to_angle(j.position)):+6.1f}" for j in s.servos
    )
    load = load_controller().servo_field("Present Load")
    loads = max((abs(load.to_units(j.load)) for j in s.servos), default=0.0)
    errors = ",".join(c["error_flags"]) or "none"
    return (
        f"  t={s.t:5.2f} s  {c['state']:<8} frame {c['play_frame']:3d}  "
        f"joints (deg, by servo ID) {servos}"
        f"  max load {loads:4.1f} %  bus reads {c['bus_reads']}  "
        f"timeouts {c['bus_timeouts']}  errors {errors}"
    )


def run_demo(settings: DemoSettings | None = None, say: Say = print) -> DemoResult:
    """Run the demo end to end (see the module docstring); ``say`` gets progress lines.
    The emulated robot is always stopped, also on Ctrl-C."""
    settings = settings or DemoSettings()
    began = time.monotonic()
    robot = load_robot(settings.robot)
    check_firmware(settings.firmware, settings.board)  # a missing one leaves no table behind
    out_dir = Path(settings.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)

    gait = serpenoid(
        robot,
        settings.amplitude,
        settings.omega,
        settings.delta,
        cycles=1,
        rate_hz=settings.rate_hz,
        loop=True,
    )
    table = gait.gait_table()
    gait_file = out_dir / "demo.gait"
    write_gait(gait_file, table)
    cycle_s = len(table.frames) * table.frame_period_ms / 1000.0
    say(
        f"1. gait: serpenoid for {robot.name}, A = {math.degrees(settings.amplitude):.0f} deg, "
        f"omega = {math.degrees(gait.parameters['omega_rad_s']):.1f} deg/s, "
        f"delta = {math.degrees(settings.delta):.0f} deg: {len(table.frames)} frames every "
        f"{table.frame_period_ms} ms ({cycle_s:.2f} s a cycle, looping) -> {gait_file}"
    )

    emulated = EmulatedRobot(robot, settings.firmware, world=settings.world, board=settings.board)
    try:
        info: ServeInfo = emulated.start()
        say(
            f"2. emulated {robot.name} running: firmware {info.firmware} {info.where()}, "
            f"servos {', '.join(map(str, info.servo_ids))} on the emulated "
            f"bus, PC link {info.pc_link}, the {settings.world} world"
        )
        with _host_blamed(), ControllerClient.open(info.pc_link) as ctl:
            report = upload_gait(ctl, table, allow_new_servos=True)
            say(
                f"3. upload: {report.summary()}; the controller's CRC 0x{report.crc:08x} "
                f"matches the file{PACING.get(info.board, '')}"
            )
            total = settings.warmup_cycles + settings.cycles
            say(
                f"4. play: {total} cycles ({settings.warmup_cycles} to settle, "
                f"{settings.cycles} measured), monitoring:"
            )
            monitor = _play(ctl, len(table.frames), total, say)
            stop(ctl)
        record = emulated.record()
        goal_t, goal_ticks = emulated.goals()
    finally:
        emulated.stop()
    comparison = compare(
        robot, table, record, goal_t, goal_ticks, settings.warmup_cycles, settings.cycles
    )
    if world_of(record) != "kinematic":
        comparison.physics, comparison.free_wheel_path = physics_effects(
            robot, table, record, comparison, settings.cycles
        )
    return DemoResult(
        settings,
        info.as_dict(),
        gait_file,
        gait.summary(),
        report,
        comparison,
        time.monotonic() - began,
        monitor,
        record,
    )


def _play(
    ctl: ControllerClient, frames_per_cycle: int, cycles: int, say: Say
) -> list[dict[str, Any]]:
    """Play the uploaded table in a loop until the firmware's Play Frame has gone through
    ``cycles`` cycles, printing a monitor line every second; returns the monitor records."""
    status = play(ctl, loop=True)
    if status["state"] != "PLAYING":
        raise DemoError(f"the controller did not start playing (state {status['state']})")
    monitor: list[dict[str, Any]] = []
    t0 = time.monotonic()
    next_monitor = t0 + MONITOR_EVERY_S / 2  # after the first telemetry round
    played, last = 0, 0
    nominal_s = cycles * frames_per_cycle * status["table"]["period_ms"] / 1000.0
    deadline = t0 + STALL_FACTOR * nominal_s
    while played < cycles * frames_per_cycle + 2:
        time.sleep(FRAME_POLL_S)
        frame = ctl.read("Play Frame")["Play Frame"]
        played += frame - last if frame >= last else frames_per_cycle - last + frame
        last = frame
        now = time.monotonic()
        if now >= next_monitor:
            s = sample(ctl, t0)
            monitor.append(s.as_record())
            say(_monitor_line(s))
            if s.registers["State"] != ctl.table.enums["State"]["PLAYING"]:
                raise DemoError("the controller stopped playing: " + render(s)[1] + _busy(s))
            next_monitor += MONITOR_EVERY_S
        if now > deadline:
            raise DemoError(
                f"the firmware played {played} frames in {now - t0:.0f} s, far "
                "slower than real time: the machine is overloaded; run the demo "
                "again when it is quieter"
            )
    return monitor


@contextlib.contextmanager
def _host_blamed() -> Iterator[None]:
    """A PC link that stops answering here is the host's doing: the controller is
    emulated on this machine, and answers at once whenever it is run, so the hint to
    check the board's power and cable does not apply."""
    try:
        yield
    except ControllerLinkError as exc:
        load = os.getloadavg()[0]
        raise DemoError(
            f"{exc.problem} (the emulated controller, on this host): the host did not run the "
            f"emulator in time (load average {load:.1f} on {os.cpu_count()} cores); run the "
            "demo again when the machine is quieter"
        ) from None


def _busy(s: Sample) -> str:
    """What a lost bus means here: the emulated servos answer on time unless the host
    deschedules the emulator, so the run is no fault of the firmware's."""
    if "BUS_LOSS" not in s.controller_record()["error_flags"]:
        return ""
    return (
        "; the emulated servos did not answer in time, which on a busy machine is the "
        "host's scheduling (the emulator was not run): rerun on an idle machine"
    )


def _physics_lines(c: Comparison) -> list[str]:
    """The physics world's part of the explanation (none for the kinematic world)."""
    if c.physics is None:
        return []
    ph = c.physics
    free = ph["predicted_free_wheels"]
    return [
        f"   physics (MuJoCo, wheel-floor mu = {ph['mu']:g}): the body has mass and its "
        f"wheels slid sideways {100 * sum(ph['wheel_slide_m']):.1f} cm in all. "
        f"Predicted with free-rolling wheels: {100 * free['distance']:.1f} cm, "
        f"{100 * ph['difference_free_wheels_m']:.1f} cm from the physics.",
        "   net work per joint "
        + ", ".join(f"{e:.3f}" for e in ph["work_j"])
        + " J (below 0: the others drove it backwards), electrical "
        + ", ".join(f"{e:.3f}" for e in ph["electrical_j"])
        + " J; peak load "
        + ", ".join(f"{100 * v:.0f}" for v in ph["peak_load"])
        + " % of stall torque.",
    ]


_REST = {
    "physics": "the physics (the body's mass, its wheels' slide)",
    "tracking error": "the servos' tracking error beyond a plain delay",
}


def verdict_line(c: Comparison) -> str:
    """The report's first line: whether the emulated robot went where the prediction
    says (within what the servos' measured lag allows), by how much, and which measured
    part of the difference is the larger."""
    p = c.predicted
    apart = (
        f"{100 * c.emulated['distance']:.1f} cm against {100 * p['distance']:.1f} cm "
        f"predicted, {100 * c.difference_m:.1f} cm apart "
        f"({100 * c.difference_m / max(p['distance'], 1e-12):.0f} %)"
    )
    allowed = f"the {100 * c.tolerance_m:.1f} cm the servos' measured lag allows"
    if c.verdict == "INVALID":
        return (
            "5. verdict: INVALID (the host did not give the emulator steady time: the "
            f"firmware's goals {c.pace.problem()}, so the servos did not follow the "
            "table's path and the result depends on the host's scheduling: rerun on an "
            f"idle machine); for the record, {apart}, more than {allowed}."
        )
    head = (
        f"5. verdict: AGREE, {apart}, within {allowed}"
        if c.within_tolerance
        else f"5. verdict: DISAGREE, {apart}, more than {allowed}"
    )
    lag = f"the servo lag ({1000 * c.lag_s:.0f} ms)"
    if c.cause == "servo lag":
        why = (
            f"mostly {lag}: the prediction with that lag is {100 * c.after_lag_m:.1f} cm "
            "from the emulated robot"
        )
    else:
        why = (
            f"mostly {_REST[c.cause]}: {lag} accounts for {100 * c.lag_part_m:.1f} cm, "
            f"{100 * c.after_lag_m:.1f} cm remain"
        )
    return f"{head}; {why}."


def summary_lines(result: DemoResult) -> list[str]:
    """What the demo found, in words."""
    c = result.comparison
    e, p = c.emulated, c.predicted
    n = result.settings.cycles

    def where(m: dict[str, float]) -> str:
        return (
            f"{100 * m['distance']:6.1f} cm towards {m['direction_deg']:+6.1f} deg "
            f"(dx {100 * m['dx']:+6.1f} cm, dy {100 * m['dy']:+6.1f} cm), "
            f"heading turned {m['turn_deg']:+6.1f} deg"
        )

    return [
        verdict_line(c),
        f"   over the {n} measured cycles "
        f"({motion_frame(load_robot(result.settings.robot))}; angles counter-clockwise):",
        f"   emulated : {where(e)}",
        f"   predicted: {where(p)}",
        f"   with lag : {where(c.predicted_lagged)}",
        f"   servo lag: the servos trail the commanded joints by "
        f"{1000 * c.lag_s:.0f} ms (largest joint error {math.degrees(c.joints.max_rad):.1f}"
        f" deg, rms {math.degrees(c.joints.rms_rad):.1f} deg); a delay that long moves the "
        f"prediction by {100 * c.lag_effect_m:.1f} cm, and the rest of the tracking error "
        f"(at most {math.degrees(c.residual_max_rad):.2f} deg) can add "
        f"{100 * RESIDUAL_SAFETY * c.sensitivity_m_per_rad * c.residual_max_rad:.1f} cm: "
        f"{100 * c.tolerance_m:.1f} cm in all.",
        c.pace.line(),
        *_physics_lines(c),
        f"   the firmware played at {c.playback_rate:.2f}x wall-clock speed (its clock in the "
        "emulator); the motion per cycle does not depend on it while the pace is steady.",
        (
            f"6. wrote {result.png} (body path: emulated vs predicted; joint angles: commanded "
            f"vs measured){_video_words(result)} and {result.gait_file}"
            if result.png is not None
            else f"6. wrote {result.gait_file}{_video_words(result)}; no picture "
            f"({install_hint('matplotlib')} draws one)"
        )
        + f"; took {result.seconds:.1f} s; nothing left running.",
    ]


def _video_words(result: DemoResult) -> str:
    video = result.settings.video
    return f", {video} (the robot's video)" if video is not None else ""
