"""The controller's gait player (``firmware/core/play_player.c``, compiled into
``snakebot._core``) on one gait table, ticked from Python: what the controller computes
each control tick, for a host that drives the servos itself (``snakebot bus play``) or
for the emulator's prediction (:mod:`snakebot.workflows.predict`)."""

from __future__ import annotations

from snakebot.core import ffi, lib
from snakebot.errors import InputError
from snakebot.facts import devices
from snakebot.facts.boards import CONTROL_TICK_MS
from snakebot.formats.gaittable import GaitTable

_AX12 = devices.ax12()
_GOAL = _AX12.register("Goal Position")
_SPEED = _AX12.register("Moving Speed")
GOAL_POSITION_ADDR, GOAL_BLOCK = _AX12.span(_GOAL.name, _SPEED.name)
"""Goal Position then Moving Speed: where one SYNC_WRITE block goes, and its bytes."""

START_SPEED = 200
"""Moving Speed (about 22 rpm) for the move to the first frame."""
START_SETTLE_S = 0.1
"""Extra bus time allowed for the move to the first frame."""
START_TOLERANCE_TICKS = 1
"""How far from the first frame a servo may stop (the factory compliance margin)."""

TICK_MS = CONTROL_TICK_MS
"""Control tick (``BOARD_CONTROL_TICK_MS``, the same on every board)."""

FULL_SPEED = 256
"""The player's speed scale for the gait as written (its unit is 1/256)."""


class PlayerError(InputError):
    """A table the controller's player refuses."""


class TablePlayer:
    """The controller's gait player (C, ``play_*``) on one table, ticked from Python.

    ``loop``: wrap from the last frame to the first (default: as the table says)."""

    def __init__(self, table: GaitTable, *, loop: bool | None = None) -> None:
        self._data = ffi.new("uint8_t[]", table.encode())  # the player keeps a pointer
        self._mem = ffi.new("uint8_t[]", lib.play_state_size())
        self._state = ffi.cast("play_state *", self._mem)
        self._params = ffi.new("play_params *")
        self._params.speed_scale = FULL_SPEED
        self._params.loop = int(table.loop if loop is None else loop)
        self._roster = ffi.new("play_joint[]", 1)  # table mode: limits come from the table
        lib.play_init(self._state)
        if not lib.play_start_table(self._state, self._data, table.size, 0):
            raise PlayerError("the controller's player refuses the table: it does not validate")

    @property
    def speed_scale(self) -> int:
        """How fast the gait runs, in 1/256 of its written speed."""
        return int(self._params.speed_scale)

    @speed_scale.setter
    def speed_scale(self, value: int) -> None:
        self._params.speed_scale = value

    @property
    def finished(self) -> bool:
        """True once a table played once has reached its last frame."""
        return bool(lib.play_finished(self._state))

    @property
    def frame(self) -> int:
        """The frame being played."""
        return int(lib.play_frame_index(self._state))

    def tick(self, now_ms: int) -> dict[int, tuple[int, int]]:
        """The outputs after a control tick at ``now_ms``: servo ID -> (goal, speed)."""
        p = self._state
        count = lib.play_tick(p, self._params, self._roster, 0, now_ms)
        out_id, goal, speed = lib.play_out_id, lib.play_out_goal, lib.play_out_speed
        return {out_id(p, j): (goal(p, j), speed(p, j)) for j in range(count)}


def goal_block(goal: int, speed: int) -> bytes:
    """Goal Position and Moving Speed as one SYNC_WRITE block."""
    return goal.to_bytes(_GOAL.size, "little") + speed.to_bytes(_SPEED.size, "little")


def goal_blocks(outputs: dict[int, tuple[int, int]]) -> dict[int, bytes]:
    """A tick's outputs as SYNC_WRITE blocks, servo ID -> block."""
    return {sid: goal_block(goal, speed) for sid, (goal, speed) in outputs.items()}
