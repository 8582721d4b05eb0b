"""What every gait generator shares: the result type, the gait table it becomes, and
the body motion predicted from the continuous gait and from the table as written."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from snakebot.errors import InputError
from snakebot.formats.gaittable import GaitTable, max_frames
from snakebot.model.kinematics import Options, Table, Trajectory, integrate_joints
from snakebot.model.robots import Friction, Robot

#: Accuracy of every prediction (Dormand-Prince 5(4)).
PREDICT_OPTIONS = Options("dopri5", rtol=1e-10, atol=1e-12)
PATH_POINTS = 300
#: How near a joint-driven trajectory may come to a singular configuration before the
#: tools warn: the reciprocal condition number of the friction problem's sticking rows
#: (the core's rcond: 1 well posed, 0 singular) dropping below this, i.e. a condition
#: number above 100. There the predicted body motion is hypersensitive to rounding,
#: timing and wheel friction.
NEAR_SINGULAR_RCOND = 1e-2


class GaitError(InputError):
    """A gait that cannot be generated as asked; the message says what to change."""


def motion_frame(robot: Robot) -> str:
    """How to read a displacement (dx, dy, dtheta): the frame of the start pose.

    A snake's reference point (x, y) is the free end of link 1 and theta is link 1's
    heading, which points along the body: link 1 is the tail and link N's free end the
    head. A serpenoid with delta, omega > 0 moves the snake head first, towards +x."""
    if robot.kind == "snake":
        return (
            "start frame: +x along link 1's heading, from the tail end (x, y) towards the "
            "head; delta, omega > 0 move the snake head first, towards +x"
        )
    return "start frame: +x along the base's heading, (x, y) at its centre"


def motion(traj: Trajectory) -> dict[str, float]:
    """Body displacement over the trajectory: (dx, dy) in the start pose's frame
    (motion_frame), dtheta."""
    start, end = traj.q[0], traj.q[-1]
    c, s = math.cos(start[2]), math.sin(start[2])
    dx, dy = end[0] - start[0], end[1] - start[1]
    return {
        "dx": float(c * dx + s * dy),
        "dy": float(-s * dx + c * dy),
        "dtheta": float(end[2] - start[2]),
    }


def path(traj: Trajectory, points: int = PATH_POINTS) -> dict[str, list[float]]:
    """At most ``points`` samples of the body pose, for plots."""
    idx = np.unique(np.linspace(0, len(traj.t) - 1, min(points, len(traj.t))).round().astype(int))
    return {
        "t": traj.t[idx].round(6).tolist(),
        "x": traj.q[idx, 0].round(9).tolist(),
        "y": traj.q[idx, 1].round(9).tolist(),
        "theta": traj.q[idx, 2].round(9).tolist(),
    }


def singularity_warnings(trajectories: dict[str, Trajectory]) -> list[dict[str, Any]]:
    """A warning (JSON-able) for each joint-driven trajectory that passes within
    NEAR_SINGULAR_RCOND of a singular configuration, worst first."""
    out = []
    for name, traj in trajectories.items():
        rcond = float(traj.stats.get("min_rcond", 1.0))
        if rcond >= NEAR_SINGULAR_RCOND:
            continue
        condition = 1.0 / rcond if rcond > 0 else None  # None: through one, exactly
        nearness = (
            f"near a singular configuration (condition number {condition:.3g}, above "
            f"{1 / NEAR_SINGULAR_RCOND:g})"
            if condition is not None
            else "through a singular configuration"
        )
        out.append(
            {
                "kind": "near_singular",
                "trajectory": name,
                "min_rcond": rcond,
                "condition": condition,
                "threshold_rcond": NEAR_SINGULAR_RCOND,
                "message": f"the {name} passes {nearness}: its predicted body motion is "
                "hypersensitive to rounding, timing and wheel friction",
            }
        )
    return sorted(out, key=lambda w: w["min_rcond"])


def frame_budget(robot: Robot, frames: int, hint: str, *params: str) -> None:
    """GaitError if ``frames`` frames do not fit the controller's table; ``hint`` says
    how to make fewer, by changing the parameters ``params``."""
    most = max_frames(robot.n_joints)
    if frames > most:
        raise GaitError(
            f"the gait needs {frames} frames but the controller holds at most "
            f"{most} for {robot.n_joints} joints: {hint}"
        ).about(*params)
    if frames < 2:
        raise GaitError(f"the gait has only {frames} frame: raise the rate or the duration")


@dataclass(frozen=True)
class TableMotion:
    """One pass of a table's joint motion and the body's: ``trajectory`` samples every
    ``period / per_interval`` (slip with it), under the robot's ``friction``."""

    trajectory: Trajectory
    friction: Friction

    def note(self) -> dict[str, Any]:
        """The JSON note of the table prediction: the friction it was predicted with."""
        return {"model": "quasi-static Coulomb", "friction": asdict(self.friction)}


def table_motion(
    robot: Robot,
    angles: np.ndarray,
    period_s: float,
    loop: bool,
    *,
    per_interval: int = 1,
    pose0: tuple[float, float, float] = (0.0, 0.0, 0.0),
    start_s: float = 0.0,
    passes: int = 1,
    friction: Friction | None = None,
) -> TableMotion:
    """The body's motion over a table as the controller plays it (angles linear between
    frames, a loop wrapping to frame 0): the one place a table becomes a prediction
    (``gait``, ``sim predict``, the demo). One pass from its first frame, or for a loop
    ``passes`` passes from table time ``start_s``, through the quasi-static friction
    model (the robot's friction unless ``friction`` is given). Times in the trajectory
    count from ``start_s``."""
    angles = np.asarray(angles, dtype=float)
    if not loop and (passes != 1 or start_s != 0.0):
        raise ValueError("a table played once has one pass, from its first frame")
    schedule = Table(angles, period_s, loop)
    intervals = (len(angles) if loop else len(angles) - 1) * passes
    traj = integrate_joints(
        robot,
        schedule,
        start_s + intervals * period_s,
        t0=start_s,
        pose0=pose0,
        samples=intervals * per_interval + 1,
        options=PREDICT_OPTIONS,
        friction=friction,
        with_slip=True,
    )
    relative = Trajectory(traj.t - start_s, traj.q, traj.slip, traj.stats)
    return TableMotion(relative, robot.friction if friction is None else friction)


def predict_table(
    robot: Robot,
    ticks: np.ndarray,
    period_s: float,
    loop: bool,
    pose0: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> tuple[Trajectory, dict[str, Any]]:
    """Body motion from the table as the controller plays it (``table_motion``: ticks
    back to angles, linear between frames, a loop wrapping to frame 0; one pass)."""
    per_interval = 4 if len(ticks) <= 1000 else 1
    played = table_motion(
        robot,
        robot.ticks_to_angles(ticks),
        period_s,
        loop,
        per_interval=per_interval,
        pose0=pose0,
    )
    return played.trajectory, played.note()


@dataclass
class Gait:
    """A generated gait: frames in ticks plus everything known about it."""

    robot: Robot
    kind: str
    parameters: dict[str, Any]
    period_ms: int
    loop: bool
    ticks: np.ndarray  # (frames, joints)
    predicted: dict[str, float]
    table: dict[str, Any]
    path: dict[str, list[float]]
    table_path: dict[str, list[float]]
    extra: dict[str, Any] = field(default_factory=dict)
    warnings: list[dict[str, Any]] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        frames = len(self.ticks)
        return self.period_ms / 1000.0 * (frames if self.loop else frames - 1)

    def summary(self) -> dict[str, Any]:
        """The JSON-able description printed by ``--json`` and stored as metadata."""
        return {
            "gait": self.kind,
            "robot": self.robot.name,
            "robot_source": self.robot.source,
            "joints": [
                {"name": j.name, "servo_id": j.servo_id, "zero_tick": j.zero_tick, "sign": j.sign}
                for j in self.robot.joints
            ],
            "parameters": self.parameters,
            "frames": len(self.ticks),
            "frame_period_ms": self.period_ms,
            "loop": self.loop,
            "duration_s": round(self.duration_s, 6),
            "frame": motion_frame(self.robot),
            "length_unit": self.robot.length_unit,
            "length_legend": self.robot.length_legend,
            "predicted": self.predicted,
            "table": self.table,
            "warnings": self.warnings,
            **self.extra,
        }

    def metadata(self) -> dict[str, Any]:
        return {**self.summary(), "path": self.path, "table_path": self.table_path}

    def gait_table(self) -> GaitTable:
        return GaitTable(
            self.robot.servo_ids,
            self.period_ms,
            self.loop,
            self.robot.tick_limits,
            self.ticks.astype(np.uint16),
            self.metadata(),
        )


def period_ms_for(rate_hz: float) -> int:
    """Frame period in whole milliseconds for a frame rate."""
    if not rate_hz > 0 or not math.isfinite(rate_hz):
        raise GaitError(f"the frame rate must be positive, in Hz, not {rate_hz}").about("rate")
    period = round(1000.0 / rate_hz)
    if not 1 <= period <= 65535:
        raise GaitError(
            f"a frame rate of {rate_hz} Hz gives a frame period of {period} ms: use a rate "
            "between 0.016 and 1000 Hz"
        ).about("rate")
    return period
