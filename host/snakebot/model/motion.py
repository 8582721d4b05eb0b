"""Where a program takes the robot: its goals step by step from the host's reference of the
fixed-point generators (:func:`snakebot.model.program_goals.predict`), integrated by the
kinematic model as a gait table's frames are; and, for ``snakebot sim predict``, the same
program played by the controller's own player (the C core, program mode) on the emulated
robot.

A program's goals hold between steps on the controller and the servos move to each at
the speed that covers the change within one step, so the joints move linearly from step
to step: the steps are the frames of a table played once, and everything the gait
tables' prediction does (``model.gait.common.table_motion``, ``workflows.predict``)
applies as is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snakebot.core import ffi, lib
from snakebot.formats.program.errors import ProgramError
from snakebot.formats.program.layout import Program
from snakebot.model.gait.common import TableMotion, table_motion
from snakebot.model.kinematics import KinematicsError
from snakebot.model.player import FULL_SPEED, TICK_MS, TablePlayer, goal_blocks
from snakebot.model.program_goals import predicted_ticks
from snakebot.model.robots import BUILTIN_ROBOTS, Robot, RobotError, load_robot


@dataclass(frozen=True)
class ProgramFrames:
    """A program's goals, one frame per program step, shaped as the gait-table prediction
    reads a table (played once, never looping)."""

    joint_ids: tuple[int, ...]
    frame_period_ms: int
    frames: np.ndarray  # frames[step, joint], ticks
    metadata: dict[str, Any] = field(default_factory=dict)
    loop: bool = False

    @property
    def frame_count(self) -> int:
        return len(self.frames)

    @classmethod
    def of(cls, program: Program) -> ProgramFrames:
        return cls(program.joint_ids, program.period_ms, predicted_ticks(program))


def joints_match(program: Program, robot: Robot) -> bool:
    """Whether the program drives exactly this robot's joints (IDs, zero ticks,
    directions), so its goals mean the angles they mean on the robot."""
    from snakebot.model.program_spec import joints_of  # spec imports this package's layout

    ours = [(j.servo_id, j.zero, j.reverse) for j in program.joints]
    theirs = [(j.servo_id, j.zero, j.reverse) for j in joints_of(robot)]
    return ours == theirs


def program_robot(program: Program, robot: str | Robot | None) -> Robot:
    """The robot a program is for: the one asked for (its joints must be the program's),
    else the built-in robot whose joints the program carries."""
    if isinstance(robot, Robot):
        chosen = robot
    elif robot is not None:
        try:
            chosen = load_robot(robot)
        except RobotError as exc:
            raise ProgramError(str(exc)) from exc
    else:
        for name in BUILTIN_ROBOTS:
            candidate = load_robot(name)
            if joints_match(program, candidate):
                return candidate
        raise ProgramError(
            f"no built-in robot has the program's joints (servos {list(program.joint_ids)}): "
            "name the robot's TOML file"
        ).about("robot")
    if not joints_match(program, chosen):
        raise ProgramError(
            f"the program drives servos {list(program.joint_ids)} with other zero ticks or "
            f"directions than {chosen.name} (servos {list(chosen.servo_ids)}): name the robot "
            "the program was built for"
        ).about("robot")
    return chosen


def program_motion(robot: Robot, program: Program, per_interval: int = 1) -> TableMotion:
    """The body's motion over the program's reference goals (ticks to angles, linear from
    step to step), from rest at the first step; ProgramError if it cannot be integrated."""
    if program.total_steps < 2:
        raise ProgramError("the program has a single step: nothing moves; give it two or more")
    angles = robot.ticks_to_angles(predicted_ticks(program))
    try:
        return table_motion(
            robot, angles, program.period_ms / 1000.0, False, per_interval=per_interval
        )
    except KinematicsError as exc:
        raise ProgramError(f"cannot predict the program's motion: {exc}") from exc


def end_pose(robot: Robot, program: Program) -> np.ndarray:
    """Where the program's reference goals take the body: x, y, theta in the start frame."""
    traj = program_motion(robot, program).trajectory
    return traj.q[-1, :3] - traj.q[0, :3]


class ProgramPlayer(TablePlayer):
    """The controller's player (C, ``play_*``) running one program, ticked from Python;
    ``speed_scale``, ``finished`` and ``tick`` as for a table."""

    def __init__(self, program: Program) -> None:  # noqa: D107 - no table to validate
        self._data = ffi.new("uint8_t[]", program.encode())  # the player keeps a pointer
        self._mem = ffi.new("uint8_t[]", lib.play_state_size())
        self._state = ffi.cast("play_state *", self._mem)
        self._params = ffi.new("play_params *")
        self._params.speed_scale = FULL_SPEED
        self._roster = ffi.new("play_joint[]", 1)  # program mode: the program's joints
        lib.play_init(self._state)
        lib.play_start_program(self._state, self._data, 0)


def player_writes(program: Program) -> tuple[float, list[dict[int, bytes]]]:
    """The SYNC_WRITE blocks the controller sends while it runs the program, one per
    control tick from t = 0 to the last step, and the tick period in seconds."""
    pass_ms = program.period_ms * (program.total_steps - 1)
    player = ProgramPlayer(program)
    blocks = [
        goal_blocks(player.tick(min(n * TICK_MS, pass_ms)))
        for n in range(math.ceil(pass_ms / TICK_MS) + 1)
    ]
    return TICK_MS / 1000.0, blocks
