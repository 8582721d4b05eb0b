"""Play a gait table on the emulated robot, with the host as bus master, and compare the
body's path with the prediction integrated from the same table.

What is played is what the controller sends: the host puts the servos at the table's
first frame, then runs the controller's own gait player (``play_player.c``, compiled into
``snakebot._core``) one control tick at a time (``TICK_MS``, as the firmware's main loop)
and sends each tick's outputs in one SYNC_WRITE of Goal Position and Moving Speed
(addresses 30-33) through snakebot's ``DxlClient`` on a ``sim://`` port: the goal
interpolated linearly in ticks between frames, the speed that of the frame step (at least
16 units). A looping table wraps from its last frame to frame 0; one pass is played.

The world (:mod:`snakebot.sim.world`) samples the servos and moves the body, starting one
tick after the first write, so each of its samples sees the goals of the tick one tick
earlier. With ideal servos (instant motion) it samples at the frame instants, where the
servos then sit exactly on the frames (when the frame period is a whole number of ticks),
so the emulated path is the table prediction (``gait.common.table_motion``, the same
function the gait's ``table`` figure comes from) up to the integrator's tolerance. With
modelled AX-12s it samples at least ``world_hz`` times a second and the servos' lag shows
up as joint tracking error and as a different body path. A table played once (a plan's,
a program's) ends held at its last frame, as the controller holds it: the world goes on
until the servos come to rest there, so the body ends where the robot stops (loaded
servos lag the goals, and the trident's planned program moves the body 7 cm after its
last goal); the prediction holds the table's last frame over those samples.

Everything runs on the bus's virtual clock: as fast as the computer allows, and the
result reports how many times faster than real time that was.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlencode

import numpy as np

from snakebot.facts import devices
from snakebot.formats.gaittable import GaitTable, read_gait
from snakebot.formats.program import Program
from snakebot.formats.program.errors import ProgramError
from snakebot.formats.program.files import is_program_file, read_program
from snakebot.formats.protocol import sync_write
from snakebot.link.transport import DxlClient
from snakebot.model.compare import JointTrack, joint_names
from snakebot.model.gait.common import (
    TableMotion,
    motion,
    motion_frame,
    singularity_warnings,
    table_motion,
)
from snakebot.model.kinematics import KinematicsError, Trajectory
from snakebot.model.motion import ProgramFrames, program_robot
from snakebot.model.motion import player_writes as program_player_writes
from snakebot.model.player import (
    GOAL_BLOCK,
    GOAL_POSITION_ADDR,
    START_SETTLE_S,
    START_SPEED,
    START_TOLERANCE_TICKS,
    TICK_MS,
    PlayerError,
    TablePlayer,
    goal_block,
    goal_blocks,
)
from snakebot.model.robots import Robot, RobotError, load_robot
from snakebot.sim.bus.bus import Bus
from snakebot.sim.physics.select import DEFAULT_WORLD, make_world, record_extras, world_of
from snakebot.sim.world import DEFAULT_BATCH, WorldRecord

_AX12 = devices.ax12()
_GOAL = _AX12.register("Goal Position")
_SPEED = _AX12.register("Moving Speed")
_PRESENT = _AX12.register("Present Position")
DEFAULT_WORLD_HZ = 100.0
MAX_WORLD_HZ = 10_000.0
"""The highest world sampling rate: 100 times the default, ten times the servos' own
control loop; beyond it a prediction's time and memory grow with no gain."""

REST_TICKS = 0.01
"""The servos are at rest once none has moved more than this (position ticks, unrounded:
a hundredth of what Present Position reports) over a world period."""

REST_MAX_S = 2.0
"""The longest a play goes on after its last goal for the servos to come to rest: loaded
AX-12s catch up with a planned table's last goal in about 0.1 s (the trident's). A play
that reaches it says so (a ``not_at_rest`` warning, :attr:`Prediction.rest_warnings`)."""


@dataclass(frozen=True)
class Rest:
    """How a play held at its last frame ended: ``periods`` world periods after the
    table, when no servo had moved more than :data:`REST_TICKS` over the last, or
    :data:`REST_MAX_S` had passed (``moving``: the most a servo moved over the last
    period, ticks; more than REST_TICKS when the cap ended it)."""

    periods: int = 0
    moving: float = 0.0

    @property
    def reached(self) -> bool:
        """Whether the servos came to rest (not ended by the cap)."""
        return self.moving <= REST_TICKS


class PredictError(PlayerError):
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
    played: TableMotion
    wall_s: float
    rest: Rest = Rest()
    """How the play ended, held at the table's last frame: the record's last
    ``rest.periods`` samples came after it, while the servos came to rest on it."""

    @property
    def rest_samples(self) -> int:
        """The record's samples after the play (``rest.periods``)."""
        return self.rest.periods

    @property
    def rest_warnings(self) -> list[dict[str, Any]]:
        """A warning (JSON-able) if the REST_MAX_S cap ended the play with a servo still
        moving, else none."""
        if self.rest.reached:
            return []
        return [
            {
                "kind": "not_at_rest",
                "after_s": REST_MAX_S,
                "moving_ticks": self.rest.moving,
                "message": f"the servos had not come to rest {REST_MAX_S:g} s after the last "
                f"goal (one still moved {self.rest.moving:.2f} ticks over the last "
                f"{self.world_period_s:g} s): the emulated end is where they were then, not "
                "where they stop",
            }
        ]

    @property
    def duration_s(self) -> float:
        return float(self.emulated.t[-1])

    @property
    def realtime_factor(self) -> float:
        """Emulated seconds per wall-clock second of the played part."""
        return self.duration_s / self.wall_s if self.wall_s > 0 else math.inf

    @property
    def joints(self) -> JointTrack:
        """The servos' angles beside the table's, per sample and joint."""
        return JointTrack(
            self.emulated.t, joint_names(self.robot), self.emulated.phi, self.predicted.q[:, 3:]
        )

    @property
    def joint_error(self) -> np.ndarray:
        """Servo angle minus table angle (radians), per sample and joint."""
        return self.joints.error

    @property
    def path_error(self) -> np.ndarray:
        """Distance between the emulated and the predicted reference point per sample."""
        d = self.emulated.pose[:, :2] - self.predicted.q[:, :2]
        return np.hypot(d[:, 0], d[:, 1])

    def summary(self) -> dict[str, Any]:
        """JSON-able report: emulated and predicted motion, their difference, speed."""
        em = self.emulated.displacement()
        pr = motion(self.predicted)
        joints = self.joints
        pred_slip = self.predicted.slip
        out: dict[str, Any] = {
            "world": world_of(self.emulated),
            "gait": self.gait,
            "robot": self.robot.name,
            "servos": "ideal" if self.ideal else self.robot.servo_model,
            "frames": self.table.frame_count,
            "frame_period_ms": self.table.frame_period_ms,
            "loop": self.table.loop,
            "duration_s": round(self.duration_s, 9),
            "frame": motion_frame(self.robot),
            "world_period_s": self.world_period_s,
            "emulated": {
                **em,
                "friction": asdict(self.emulated.friction),
                "slip_max": self.emulated.slip_max(),
                "slip_distance": [float(v) for v in self.emulated.slip_distance()],
                "samples": len(self.emulated.t),
                "rest_s": round(self.rest_samples * self.world_period_s, 9),
                **record_extras(self.emulated),
            },
            "predicted": {
                **pr,
                "slip_max": float(np.abs(pred_slip).max()) if pred_slip is not None else 0.0,
                **self.played.note(),
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
                "joint_max_rad": joints.max_rad,
                "joint_rms_rad": joints.rms_rad,
            },
            "realtime_factor": self.realtime_factor,
            "wall_s": self.wall_s,
            "warnings": [
                *singularity_warnings({"prediction from the table": self.predicted}),
                *self.rest_warnings,
            ],
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
                    "robot: name it (snake5, snake3, trident or a .toml)"
                ).about("robot")
        try:
            chosen = load_robot(name)
        except RobotError as exc:
            made_for = (
                f" (the gait was made for robot {name!r}; name another description to use that)"
                if robot is None  # the metadata's robot, not the one asked for
                else ""
            )
            raise PredictError(f"{exc}{made_for}").about("robot") from exc
    if tuple(table.joint_ids) != chosen.servo_ids:
        raise PredictError(
            f"the table drives servos {list(table.joint_ids)} but {chosen.name} has servos "
            f"{list(chosen.servo_ids)}: name the robot the gait was made for"
        ).about("robot")
    return chosen


def player_writes(table: GaitTable) -> tuple[float, list[dict[int, bytes]]]:
    """The SYNC_WRITE blocks (servo ID -> goal, speed little-endian) the controller sends
    over one pass of the table, one per control tick from t = 0 to the pass's end, and
    the tick period in seconds."""
    period_ms = table.frame_period_ms
    pass_ms = period_ms * (table.frame_count if table.loop else table.frame_count - 1)
    player = TablePlayer(table)
    blocks = []
    made: dict[tuple, dict[int, bytes]] = {}  # a frame held over several ticks: one dict
    for n in range(math.ceil(pass_ms / TICK_MS) + 1):
        outputs = player.tick(min(n * TICK_MS, pass_ms))
        key = tuple(outputs.items())
        if key not in made:
            made[key] = goal_blocks(outputs)
        blocks.append(made[key])
    return TICK_MS / 1000.0, blocks


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
        {sid: goal_block(int(g), START_SPEED) for sid, g in zip(ids, first, strict=True)},
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
    world: str = DEFAULT_WORLD,
    mu: float | None = None,
    writes: tuple[float, list[dict[int, bytes]]] | None = None,
    until_rest: bool = True,
) -> tuple[WorldRecord, float, float, int]:
    """Play ``table`` once from the servos' current state (``ideal``: they are ideal
    servos, so the world samples at the frame instants); returns the world's record,
    its sampling period, the wall time the play took and how many of the record's last
    samples came after the play, while the servos came to rest on a table played once.
    ``writes``: the tick period and blocks to send instead of the table player's (a
    program's, say); ``until_rest=False`` ends the play with the table even so."""
    if not 0 < world_hz <= MAX_WORLD_HZ:
        raise PredictError(
            f"the world's sampling rate must be more than 0 and at most {MAX_WORLD_HZ:g} Hz, "
            f"not {world_hz} Hz"
        )
    period = table.frame_period_ms / 1000.0
    per_frame = 1 if ideal else max(1, math.ceil(period * world_hz - 1e-9))
    world_period = period / per_frame
    tick, blocks = player_writes(table) if writes is None else writes
    # the packets are known before the play starts: encode them once, as a host loop
    # should (and each distinct one once: a frame held over several ticks repeats its own)
    encoded: dict[tuple[tuple[int, bytes], ...], bytes] = {}
    packets = []
    for n, b in enumerate(blocks):
        if b:
            key = tuple(b.items())
            if key not in encoded:
                encoded[key] = sync_write(GOAL_POSITION_ADDR, GOAL_BLOCK, b)
            packets.append((n, encoded[key]))
    intervals = table.frame_count if table.loop else table.frame_count - 1
    duration = intervals * period
    start = bus.now
    # One tick late: a sample at t sees the goals sent at t - tick (the world samples
    # before a write due at the same instant), so its samples at the frame instants see
    # the frames themselves. Built before the clock starts: MuJoCo's model compiles once,
    # outside the play.
    body = make_world(
        world, bus, robot, period=world_period, start=start + tick, batch=batch, mu=mu
    )
    wall0 = time.perf_counter()
    for n, packet in packets:
        bus.run_until(start + min(n * tick, duration))
        client.send(packet)  # SYNC_WRITE: no reply to wait for
    end = start + tick + duration + 0.5 * world_period
    bus.run_until(end - world_period)
    before = bus.positions(robot.servo_ids)
    bus.run_until(end)
    # a table played once ends held at its last frame: the body ends where the servos
    # come to rest on it (ideal ones are there at once; a loop goes on into its next pass)
    settles = until_rest and not (ideal or table.loop)
    rest = come_to_rest(bus, robot, world_period, before) if settles else Rest()
    body.stop()
    record = body.record()
    wall = time.perf_counter() - wall0
    expected = intervals * per_frame + 1 + rest.periods
    if len(record.t) != expected:  # pragma: no cover - a clock bug, not a user error
        raise PredictError(f"the world took {len(record.t)} samples, expected {expected}")
    return record, world_period, wall, rest


def come_to_rest(bus: Bus, robot: Robot, period: float, before: list[float]) -> Rest:
    """Run ``bus`` a ``period`` at a time until ``robot``'s servos are at rest (none moved
    more than :data:`REST_TICKS` over a period; they were at ``before`` one period ago),
    for at most :data:`REST_MAX_S`; returns the periods run and the last period's move."""
    periods = 0
    now = bus.positions(robot.servo_ids)
    most = math.ceil(REST_MAX_S / period - 1e-9)
    moving = max(abs(a - b) for a, b in zip(now, before, strict=True))
    while periods < most and moving > REST_TICKS:
        bus.run_until(bus.now + period)
        periods += 1
        before, now = now, bus.positions(robot.servo_ids)
        moving = max(abs(a - b) for a, b in zip(now, before, strict=True))
    return Rest(periods, moving)


def predict_table(
    robot: Robot, table: GaitTable, samples: int, rest: int = 0
) -> tuple[Trajectory, TableMotion]:
    """The body path integrated straight from the table, as the gait's ``table`` figure
    is (``table_motion``: ticks to angles, linear in between, the robot's friction, as the
    world does), at ``samples`` evenly spaced times over one pass (slip: mid-interval, as the world
    records it), then held at the last frame for ``rest`` more samples (the play's
    servos coming to rest, see ``play``); returns the trajectory and the table motion it
    came from."""
    samples -= rest
    intervals = table.frame_count if table.loop else table.frame_count - 1
    per_sample, odd = divmod(samples - 1, intervals)
    if odd or per_sample < 1:  # pragma: no cover - the world samples whole frames
        raise PredictError(f"{samples} samples do not divide the table's {intervals} intervals")
    try:
        played = table_motion(
            robot,
            robot.ticks_to_angles(table.frames),
            table.frame_period_ms / 1000.0,
            table.loop,
            per_interval=2 * per_sample,
        )
    except KinematicsError as exc:
        raise PredictError(f"cannot predict the table's motion: {exc}") from exc
    traj = played.trajectory
    assert traj.slip is not None
    t, q = traj.t[::2], traj.q[::2]
    slip = np.vstack([np.zeros((1, traj.slip.shape[1])), traj.slip[1::2]])
    if rest:
        t = np.concatenate([t, t[-1] + (t[1] - t[0]) * np.arange(1, rest + 1)])
        q = np.vstack([q, np.repeat(q[-1:], rest, axis=0)])
        slip = np.vstack([slip, np.zeros((rest, slip.shape[1]))])
    return Trajectory(t, q, slip, traj.stats), played


def predict_gait(
    gait: str | Path | GaitTable, robot: str | Robot | None = None, **options: Any
) -> Prediction:
    """Play a gait table (a file or a ``GaitTable``) on an emulated robot and compare;
    ``options`` as ``emulate``'s."""
    table = gait if isinstance(gait, GaitTable) else read_gait(gait)
    name = "<table>" if isinstance(gait, GaitTable) else str(gait)
    chosen = resolve_robot(table, robot)
    if table.frame_count < 2:
        raise PredictError("the table has a single frame: nothing moves; give it two or more")
    return emulate(name, chosen, table, None, **options)


def emulate(
    name: str,
    robot: Robot,
    table: Any,
    writes: tuple[float, list[dict[int, bytes]]] | None,
    *,
    ideal: bool = False,
    world_hz: float = DEFAULT_WORLD_HZ,
    batch: int = DEFAULT_BATCH,
    world: str = DEFAULT_WORLD,
    mu: float | None = None,
    until_rest: bool = True,
) -> Prediction:
    """Put the emulated robot at the table's first frame, play it (``writes``: the blocks
    to send instead of the table player's, and ``until_rest``, see ``play``) and compare
    with the table's prediction. ``table`` is a GaitTable or anything with its frames,
    frame_period_ms, frame_count, loop and metadata (a program's steps,
    ``model.motion``). ``ideal``: ideal servos; ``batch``: samples the world integrates
    per C call (results do not depend on it); ``world``: "kinematic" or "mujoco"
    (``mu``: its wheel-floor friction)."""
    if ideal and world != "kinematic":
        raise PredictError(
            f"ideal servos have no torque: the {world} world needs servos that can fall short"
        ).about("ideal", "world")
    client = DxlClient(sim_url(robot, ideal), echo=False)
    try:
        bus: Bus = client.port.bus
        move_to_start(client, bus, robot, table.frames[0])
        record, world_period, wall, rest = play(
            client,
            bus,
            robot,
            table,
            ideal=ideal,
            world_hz=world_hz,
            batch=batch,
            world=world,
            mu=mu,
            writes=writes,
            until_rest=until_rest,
        )
    finally:
        client.close()
    predicted, played = predict_table(robot, table, len(record.t), rest.periods)
    return Prediction(
        name, robot, table, ideal, world_period, record, predicted, played, wall, rest
    )


def predict_program(
    path: str | Path,
    robot: str | Robot | None = None,
    **options: Any,
) -> Any:
    """:func:`predict_gait` for a program file: the controller's player runs it on the
    emulated robot (``options`` as there), beside the body path its reference goals
    predict (:mod:`snakebot.model.motion`)."""
    program = read_program(path)
    return emulate_program(str(path), program, program_robot(program, robot), **options)


def emulate_program(name: str, program: Program, robot: Robot, **options: Any) -> Prediction:
    """``program`` run by the controller's player on the emulated ``robot`` (``options``
    as :func:`emulate`'s), beside the body path its reference goals predict."""
    if program.total_steps < 2:
        raise ProgramError("the program has a single step: nothing moves; give it two or more")
    return emulate(
        name, robot, ProgramFrames.of(program), program_player_writes(program), **options
    )


PROGRAM_SOURCE = (
    "integrated from the program's goals at every step (the host's reference of the "
    "controller's generators), linear from step to step"
)
"""How a program's prediction is made, for its summary."""


def predict_file(
    path: str | Path, robot: str | Robot | None = None, **options: Any
) -> tuple[Prediction, dict[str, Any]]:
    """:func:`predict_program` or :func:`predict_gait`, by what ``path`` holds (``options``
    as theirs): the prediction and its summary, which says how the path was predicted."""
    if not is_program_file(path):
        result = predict_gait(path, robot, **options)
        return result, result.summary()
    result = predict_program(path, robot, **options)
    summary = result.summary()
    summary["predicted"]["source"] = PROGRAM_SOURCE
    return result, summary
