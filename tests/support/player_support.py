"""The C player (play_*) driven directly, and the float references it is checked against."""

from __future__ import annotations

import math

import numpy as np

from snakebot.core import ffi, lib
from snakebot.facts import devices
from snakebot.formats.gaittable import GaitTable

# The exact values the fixed-point player approximates, from the AX-12A's description.
_AX12 = devices.ax12()
_POSITION = _AX12.require_position()
_SPEED = _AX12.register("Moving Speed")
TICKS_PER_RAD = _POSITION.ticks_per_rad
UNITS_PER_TICK_S = 1 / _SPEED.to_units(1, "deg/s") / _POSITION.scale.per_unit("deg")
SPEED_MAX = _SPEED.encoding.magnitude_mask


class Player:
    def __init__(self, roster: list[tuple[int, int, int, int, int]] | None = None) -> None:
        self._mem = ffi.new("uint8_t[]", lib.play_state_size())
        self.p = ffi.cast("play_state *", self._mem)
        lib.play_init(self.p)
        self.params = ffi.new("play_params *")
        self.params.speed_scale = 256
        self.params.loop = 1
        self.set_roster(roster or [])
        self._table = None

    def set_roster(self, roster: list[tuple[int, int, int, int, int]]) -> None:
        """(id, reverse, zero, min, max) per joint."""
        self.roster = ffi.new("play_joint[]", max(len(roster), 1))
        for k, (sid, rev, zero, lo, hi) in enumerate(roster):
            self.roster[k] = {"id": sid, "reverse": rev, "zero": zero, "min": lo, "max": hi}
        self.roster_count = len(roster)

    def start_table(self, table: GaitTable, now: int = 0) -> bool:
        self._table = ffi.new("uint8_t[]", table.encode())  # kept alive while it plays
        self.params.loop = int(table.loop)
        return lib.play_start_table(self.p, self._table, table.size, now)

    def start_serpenoid(self, count: int, now: int = 0) -> bool:
        return lib.play_start_serpenoid(self.p, count, now)

    def tick(self, now: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ids, goals, speeds) after a tick at `now` ms."""
        n = lib.play_tick(self.p, self.params, self.roster, self.roster_count, now)
        ids = np.array([lib.play_out_id(self.p, j) for j in range(n)], dtype=int)
        goals = np.array([lib.play_out_goal(self.p, j) for j in range(n)], dtype=int)
        speeds = np.array([lib.play_out_speed(self.p, j) for j in range(n)], dtype=int)
        return ids, goals, speeds

    @property
    def mode(self) -> int:
        return lib.play_mode(self.p)


def table_reference(table: GaitTable, u_ms: float) -> np.ndarray:
    """Goals (float) of `table` at table time u (ms), interpolated linearly."""
    frames = table.frames.astype(float)
    period = table.frame_period_ms
    if table.loop:
        points = np.vstack([frames, frames[:1]])
        u = u_ms % (table.frame_count * period)
    else:
        points = frames
        u = min(u_ms, (table.frame_count - 1) * period)
    times = np.arange(len(points)) * period
    return np.array([np.interp(u, times, points[:, j]) for j in range(table.joint_count)])


def speed_reference(ticks_per_s: float) -> float:
    return min(max(math.ceil(ticks_per_s * UNITS_PER_TICK_S), lib.PLAY_MIN_SPEED), SPEED_MAX)


def serpenoid_reference(amp: float, phase: float, delta: float, phi0: float, k: int) -> float:
    """Joint k's angle offset in ticks (float): (A sin(phase + k delta) + phi0) * ticks/rad."""
    return (amp * math.sin(phase + k * delta) + phi0) * TICKS_PER_RAD
