"""Play a gait table on the emulated robot, with the host as bus master, and compare the
body's path with the prediction integrated from the same table.

What is played, as a PC with a USB2Dynamixel adapter (and no controller) would: the host
puts the servos at the table's first frame, then at every frame time t_k = k * period it
sends one SYNC_WRITE of Goal Position and Moving Speed (addresses 30-33) to every joint,
through snakebot's ``DxlClient`` on a ``sim://`` port. The goal is the next frame, and
the speed is the one that covers the step to it in one frame period (rounded up, at
least 16 units, exactly as the controller's player computes it: ``play_speed_units``
from the C core), so a servo that keeps up arrives at each frame on time. A looping table
wraps from its last frame to frame 0; one pass is played.

The world (:mod:`snakebot.sim.world`) samples the servos and moves the body. With ideal
servos (instant motion) it samples at the frame instants, where the servos sit exactly on
the frames, so the emulated path is the table prediction (``Gait.table``: ticks back to
angles, linear in between) up to the integrator's tolerance. With modelled AX-12s it
samples at least ``world_hz`` times a second and the servos' lag shows up as joint
tracking error and as a different body path.

Everything runs on the bus's virtual clock: as fast as the computer allows, and the
result reports how many times faster than real time that was.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlencode

import numpy as np

from snakebot import devices
from snakebot.core import lib
from snakebot.errors import SnakebotError
from snakebot.gait.common import PREDICT_OPTIONS, motion
from snakebot.gaittable import GaitTable, read_gait
from snakebot.kinematics import KinematicsError, Table, Trajectory, integrate_joints
from snakebot.protocol import sync_write
from snakebot.robots import Robot, RobotError, load_robot
from snakebot.sim.bus import Bus
from snakebot.sim.world import DEFAULT_BATCH, SINGULAR_CODES, World, WorldRecord, fallback_c_t
from snakebot.transport import DxlClient

_AX12 = devices.ax12()
_GOAL = _AX12.register("Goal Position")
_SPEED = _AX12.register("Moving Speed")
_PRESENT = _AX12.register("Present Position")
GOAL_POSITION_ADDR, GOAL_BLOCK = _AX12.span(_GOAL.name, _SPEED.name)
"""Goal Position then Moving Speed: where one SYNC_WRITE block goes, and its bytes."""
START_SPEED = 200
"""Moving Speed (about 22 rpm) for the move to the first frame."""
START_SETTLE_S = 0.1
"""Extra bus time allowed for the move to the first frame."""
START_TOLERANCE_TICKS = 1
"""How far from the first frame a servo may stop (the factory compliance margin)."""
DEFAULT_WORLD_HZ = 100.0


class PredictError(SnakebotError):
    """A gait that cannot be played on the emulated robot as asked."""


@dataclass(frozen=True)
class Prediction:
    """The emulated run beside the prediction from the same table."""

    gait: str
    robot: Robot
    table: GaitTable
    ideal: bool
    world_period_s: float
    emulated: WorldRecord
    predicted: Trajectory
    predicted_c_t: float
    wall_s: float

    @property
    def duration_s(self) -> float:
        return float(self.emulated.t[-1])

    @property
    def realtime_factor(self) -> float:
        """Emulated seconds per wall-clock second of the played part."""
        return self.duration_s / self.wall_s if self.wall_s > 0 else math.inf

    @property
    def joint_error(self) -> np.ndarray:
        """Servo angle minus table angle (radians), per sample and joint."""
        return self.emulated.phi - self.predicted.q[:, 3:]

    @property
    def path_error(self) -> np.ndarray:
        """Distance between the emulated and the predicted reference point per sample."""
        d = self.emulated.pose[:, :2] - self.predicted.q[:, :2]
        return np.hypot(d[:, 0], d[:, 1])

    def summary(self) -> dict[str, Any]:
        """JSON-able report: emulated and predicted motion, their difference, speed."""
        em = self.emulated.displacement()
        pr = motion(self.predicted)
        err = self.joint_error
        pred_slip = self.predicted.slip
        out: dict[str, Any] = {
            "gait": self.gait,
            "robot": self.robot.name,
            "servos": "ideal" if self.ideal else self.robot.servo_model,
            "frames": self.table.frame_count,
            "frame_period_ms": self.table.frame_period_ms,
            "loop": self.table.loop,
            "duration_s": round(self.duration_s, 9),
            "world_period_s": self.world_period_s,
            "emulated": {
                **em,
                "c_t": self.emulated.c_t,
                "regularised_intervals": int(self.emulated.regularised.sum()),
                "fallback_c_t": self.emulated.fallback_c_t,
                "slip_max": self.emulated.slip_max(),
                "slip_distance": [float(v) for v in self.emulated.slip_distance()],
                "samples": len(self.emulated.t),
            },
            "predicted": {
                **pr,
                "slip_max": float(np.abs(pred_slip).max()) if pred_slip is not None else 0.0,
                "c_t": self.predicted_c_t,
                "source": "integrated from the table's frames (ticks to angles, linear in "
                "between, as the controller plays them)",
            },
            "difference": {
                "dx": em["dx"] - pr["dx"],
                "dy": em["dy"] - pr["dy"],
                "dtheta": em["dtheta"] - pr["dtheta"],
                "path_max": float(self.path_error.max()),
                "heading_max": float(
                    np.abs(self.emulated.pose[:, 2] - self.predicted.q[:, 2]).max()
                ),
                "joint_max_rad": float(np.abs(err).max()),
                "joint_rms_rad": float(np.sqrt(np.mean(err * err))),
            },
            "realtime_factor": self.realtime_factor,
            "wall_s": self.wall_s,
        }
        meta_table = self.table.metadata.get("table")
        if isinstance(meta_table, dict):
            out["metadata_table"] = meta_table
        return out


def resolve_robot(table: GaitTable, robot: str | Robot | None) -> Robot:
    """The robot to emulate: the one asked for, else the one the gait's metadata names;
    its servo IDs must be the table's."""
    if isinstance(robot, Robot):
        chosen = robot
    else:
        name = robot
        if name is None:
            meta = table.metadata
            name = meta.get("robot_source") or meta.get("robot")
            if not name:
                raise PredictError(
                    "the gait table has no metadata (FILE.json) naming its "
                    "robot: pass --robot snake5 (or snake3, trident, a .toml)"
                )
        try:
            chosen = load_robot(name)
        except RobotError as exc:
            raise PredictError(
                f"{exc} (the gait was made for robot {name!r}; pass --robot "
                "to choose another description)"
            ) from exc
    if tuple(table.joint_ids) != chosen.servo_ids:
        raise PredictError(
            f"the table drives servos {list(table.joint_ids)} but {chosen.name} has servos "
            f"{list(chosen.servo_ids)}: pass --robot with the robot the gait was made for"
        )
    return chosen


def frame_speeds(frames: np.ndarray, period_ms: int, loop: bool) -> tuple[np.ndarray, np.ndarray]:
    """Goals and Moving Speeds of the writes: write k (at k * period) sends frame k + 1
    (frame 0 after the last, for a loop) at the speed that covers the step in one
    period, as the controller's player computes it."""
    frames = np.asarray(frames, dtype=np.int64)
    nxt = np.roll(frames, -1, axis=0) if loop else frames[1:]
    cur = frames if loop else frames[:-1]
    steps = np.abs(nxt - cur)
    speeds = np.array(
        [[lib.play_speed_units(int(s) * 1000 * 256 // period_ms) for s in row] for row in steps],
        dtype=np.int64,
    ).reshape(steps.shape)
    return nxt, speeds


def sync_blocks(
    ids: tuple[int, ...], goals: np.ndarray, speeds: np.ndarray
) -> list[dict[int, bytes]]:
    """One SYNC_WRITE payload (ID -> goal, speed little-endian) per write."""
    return [
        {sid: _goal_block(int(g), int(v)) for sid, g, v in zip(ids, grow, vrow, strict=True)}
        for grow, vrow in zip(goals, speeds, strict=True)
    ]


def _goal_block(goal: int, speed: int) -> bytes:
    """Goal Position and Moving Speed as one SYNC_WRITE block."""
    return goal.to_bytes(_GOAL.size, "little") + speed.to_bytes(_SPEED.size, "little")


def sim_url(robot: Robot, ideal: bool) -> str:
    """The ``sim://`` port of an emulated bus with this robot's servos."""
    return "sim://?" + urlencode(
        {"robot": robot.source or robot.name, "ideal": "1" if ideal else "0"}
    )


def move_to_start(client: DxlClient, bus: Bus, robot: Robot, first: np.ndarray) -> None:
    """Send every joint to the first frame at a gentle speed, wait for it, and check the
    servos' Present Position over the bus."""
    ids = robot.servo_ids
    client.sync_write(
        _GOAL.address,
        GOAL_BLOCK,
        {sid: _goal_block(int(g), START_SPEED) for sid, g in zip(ids, first, strict=True)},
    )
    here = np.array(bus.positions(ids))
    distance = float(np.abs(here - first).max())
    ticks_per_deg = _AX12.require_position().scale.per_unit("deg")
    ticks_per_s = _SPEED.to_units(START_SPEED, "deg/s") * ticks_per_deg
    bus.run_until(bus.now + distance / ticks_per_s + START_SETTLE_S)
    for sid, goal in zip(ids, first, strict=True):
        present = client.read_u16(sid, _PRESENT.address)
        if abs(present - int(goal)) > START_TOLERANCE_TICKS:
            raise PredictError(
                f"servo {sid} stopped at {present} ticks, not at the first frame's {int(goal)}: "
                "check the servo model and supply voltage of the emulated robot"
            )


def play(
    client: DxlClient,
    bus: Bus,
    robot: Robot,
    table: GaitTable,
    *,
    ideal: bool,
    world_hz: float = DEFAULT_WORLD_HZ,
    batch: int = DEFAULT_BATCH,
) -> tuple[WorldRecord, float, float]:
    """Play ``table`` once from the servos' current state (``ideal``: they are ideal
    servos, so the world samples at the frame instants); returns the world's record,
    its sampling period and the wall time the play took."""
    if not world_hz > 0:
        raise PredictError(f"the world's sampling rate must be positive, not {world_hz} Hz")
    period = table.frame_period_ms / 1000.0
    per_frame = 1 if ideal else max(1, math.ceil(period * world_hz - 1e-9))
    world_period = period / per_frame
    goals, speeds = frame_speeds(table.frames, table.frame_period_ms, table.loop)
    # the packets are known before the play starts: encode them once, as a host loop should
    packets = [
        sync_write(GOAL_POSITION_ADDR, GOAL_BLOCK, block)
        for block in sync_blocks(robot.servo_ids, goals, speeds)
    ]
    writes = len(packets)
    duration = writes * period
    wall0 = time.perf_counter()
    start = bus.now
    world = World(bus, robot, period=world_period, start=start, batch=batch)
    for k, packet in enumerate(packets):
        bus.run_until(start + k * period)
        client.send(packet)  # SYNC_WRITE: no reply to wait for
    bus.run_until(start + duration + 0.5 * world_period)
    world.stop()
    record = world.record()
    wall = time.perf_counter() - wall0
    expected = writes * per_frame + 1
    if len(record.t) != expected:  # pragma: no cover - a clock bug, not a user error
        raise PredictError(f"the world took {len(record.t)} samples, expected {expected}")
    return record, world_period, wall


def predict_table(robot: Robot, table: GaitTable, samples: int) -> tuple[Trajectory, float]:
    """The body path integrated straight from the table, as the gait's ``table`` figure
    is (ticks to angles, linear in between, the robot's c_t, or a small one over the
    whole table if ideal wheels are singular on it), at ``samples`` evenly spaced times
    over one pass (slip: mid-interval, as the world records it); returns the trajectory
    and the c_t used."""
    angles = robot.ticks_to_angles(table.frames)
    period = table.frame_period_ms / 1000.0
    frames = table.frame_count
    duration = period * (frames if table.loop else frames - 1)
    schedule = Table(angles, period, table.loop)
    c_t = robot.c_t

    def run(c_t: float) -> Trajectory:
        return integrate_joints(
            robot,
            schedule,
            duration,
            samples=2 * samples - 1,
            options=PREDICT_OPTIONS,
            c_t=c_t,
            with_slip=True,
        )

    try:
        try:
            traj = run(c_t)
        except KinematicsError as exc:
            fallback = fallback_c_t(robot, c_t)
            if fallback is None or exc.code not in SINGULAR_CODES:
                raise
            c_t = fallback
            traj = run(c_t)
    except KinematicsError as exc:
        raise PredictError(f"cannot predict the table's motion: {exc}") from exc
    assert traj.slip is not None
    slip = np.vstack([np.zeros((1, traj.slip.shape[1])), traj.slip[1::2]])
    return Trajectory(traj.t[::2], traj.q[::2], slip, traj.stats), c_t


def predict_gait(
    gait: str | Path | GaitTable,
    robot: str | Robot | None = None,
    *,
    ideal: bool = False,
    world_hz: float = DEFAULT_WORLD_HZ,
    batch: int = DEFAULT_BATCH,
) -> Prediction:
    """Play a gait table (a file or a ``GaitTable``) on an emulated robot and compare.
    ``batch``: samples the world integrates per C call (results do not depend on it)."""
    table = gait if isinstance(gait, GaitTable) else read_gait(gait)
    name = "<table>" if isinstance(gait, GaitTable) else str(gait)
    chosen = resolve_robot(table, robot)
    if table.frame_count < 2:
        raise PredictError("the table has a single frame: nothing moves; give it two or more")
    client = DxlClient(sim_url(chosen, ideal), echo=False)
    try:
        bus: Bus = client.port.bus
        move_to_start(client, bus, chosen, table.frames[0])
        record, world_period, wall = play(
            client, bus, chosen, table, ideal=ideal, world_hz=world_hz, batch=batch
        )
    finally:
        client.close()
    predicted, predicted_c_t = predict_table(chosen, table, len(record.t))
    return Prediction(
        name, chosen, table, ideal, world_period, record, predicted, predicted_c_t, wall
    )
