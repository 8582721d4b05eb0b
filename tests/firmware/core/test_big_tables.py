"""Tables as large as the CM-530 holds (issue #13): the controller's C device logic with the
CM-530's table arena and capacity (firmware/boards/cm530/board.h) uploads, commits and
plays a table of the full capacity, takes an upload beside a playing table when the arena
has room for both, refuses one that would land on the playing table, and keeps the QEMU
board's promise that an upload never touches the table playing."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from ctl_support import CTL, CTL_ID, Device, telemetry_reply
from firmware_support import board_value
from test_ctl_bus import decode_sync_write

from snakebot.core import ffi, lib
from snakebot.formats.gaittable import GaitTable, max_frames
from snakebot.formats.protocol import ErrorFlags, write
from snakebot.link.controller import ControllerErrors, State, UploadResult, chunk_writes

IDS = (11, 12, 13, 14)
PERIOD_MS = 20


def board(name: str) -> tuple[int, int]:
    """(Table Capacity, table arena bytes) as the board's board.h sets them."""
    return board_value(name, "BOARD_TABLE_CAPACITY"), board_value(name, "BOARD_TABLE_ARENA")


CM530 = board("cm530")
QEMU = board("qemu")


def table_of(size: int, seed: int = 0) -> GaitTable:
    """A looping table of 4 joints, at most `size` bytes, whose every frame differs."""
    count = min((size - 16 - 6 * len(IDS)) // (2 * len(IDS)), max_frames(len(IDS)))
    k = np.arange(count)[:, None]
    frames = 300 + (k * 7 + seed * 13 + np.arange(len(IDS)) * 101) % 400
    return GaitTable(IDS, PERIOD_MS, True, ((250, 750),) * len(IDS), frames)


def play_to(dev: Device, frame: int, step_ms: int = 500) -> dict[int, int]:
    """Tick from 0 (torque on) to the table time of `frame`, `step_ms` apart (the player
    catches up at most a second a tick); the goals sent at the last tick."""
    replies = {sid: telemetry_reply(sid) for sid in IDS}
    dev.tick(0, replies)
    for now in range(step_ms, frame * PERIOD_MS, step_ms):
        dev.tick(now, replies)
    goals, _read = dev.tick(frame * PERIOD_MS, replies)
    return {sid: goal for sid, (goal, _speed) in decode_sync_write(goals).items()}


def frame_goals(t: GaitTable, frame: int) -> dict[int, int]:
    return {sid: int(v) for sid, v in zip(IDS, t.frames[frame], strict=True)}


def active_bytes(dev: Device) -> bytes:
    n = ffi.new("size_t *")
    p = lib.ctl_active_table(dev.d, n)
    return b"" if p == ffi.NULL else bytes(ffi.buffer(p, n[0]))


def test_the_cm530_holds_at_least_32_kb_and_the_qemu_board_2_kb_in_the_same_ram():
    capacity, arena = CM530
    assert capacity >= 32 * 1024 and arena < 64 * 1024
    assert QEMU == (2048, 4096)  # the staging area and the table side by side, as before


def test_a_table_of_the_full_capacity_uploads_commits_and_plays():
    capacity, arena = CM530
    dev = Device(capacity, arena)
    t = table_of(capacity)
    data = t.encode()
    assert capacity - 8 < len(data) <= capacity
    assert dev.upload(data) == UploadResult.OK
    assert dev.get("Table Size") == len(data) and dev.get("Table CRC") == zlib.crc32(data)
    assert dev.get("Table Frames") == t.frame_count
    assert active_bytes(dev) == data
    assert dev.command("PLAY") == 0 and dev.state == State.PLAYING
    last = t.frame_count - 1  # the last frame lies at the far end of the 32 KB
    assert play_to(dev, last) == frame_goals(t, last)
    assert dev.get("Play Frame") == last


def test_one_byte_more_than_the_capacity_is_refused():
    capacity, arena = CM530
    dev = Device(capacity, arena)
    offset = CTL.register("Upload Offset").address
    r = dev.one(write(CTL_ID, offset, (capacity - 1).to_bytes(2, "little") + bytes(2)))
    assert r.error == ErrorFlags.RANGE and dev.flags & ControllerErrors.UPLOAD_LENGTH
    assert dev.commit(capacity + 1, 0) == 0
    assert dev.get("Upload Result") == UploadResult.BAD_LENGTH


def test_an_upload_beside_a_playing_table_that_leaves_room_for_it():
    capacity, arena = CM530
    dev = Device(capacity, arena)
    playing = table_of(arena - capacity)  # ends where the staging area begins
    assert dev.upload(playing.encode()) == UploadResult.OK
    assert dev.command("PLAY") == 0
    new = table_of(capacity, seed=1).encode()
    dev.upload(new, commit=False)  # every chunk WRITE answered without error
    # every chunk of the full-size upload landed while the old table went on playing
    assert dev.state == State.PLAYING
    assert play_to(dev, 100) == frame_goals(playing, 100)
    assert dev.commit(len(new), zlib.crc32(new)) == 0
    assert dev.get("Upload Result") == UploadResult.OK and active_bytes(dev) == new
    assert dev.state == State.IDLE  # a commit stops playback, as always


def test_an_upload_that_would_land_on_the_playing_table_is_refused_until_stopped():
    capacity, arena = CM530
    dev = Device(capacity, arena)
    playing = table_of(arena - capacity + 2048)  # reaches 2 KB into the staging area
    old = playing.encode()
    assert dev.upload(old) == UploadResult.OK
    assert dev.command("PLAY") == 0
    new = table_of(1024, seed=2).encode()  # even a small one: it starts on the table
    (first, payload), *_ = chunk_writes(new)
    r = dev.one(write(CTL_ID, first, payload))
    assert r.error == ErrorFlags.RANGE
    assert dev.get("Upload Result") == UploadResult.NO_ROOM_WHILE_PLAYING
    assert dev.flags & ControllerErrors.UPLOAD_LENGTH
    # a commit meanwhile says why too (a pipelined upload sends it after the refusal)
    assert dev.commit(len(new), zlib.crc32(new)) == 0
    assert dev.get("Upload Result") == UploadResult.NO_ROOM_WHILE_PLAYING
    # the table is untouched and still plays
    assert active_bytes(dev) == old and dev.state == State.PLAYING
    assert play_to(dev, playing.frame_count - 1) == frame_goals(playing, playing.frame_count - 1)
    # stopped, the same upload goes through and replaces it
    assert dev.command("STOP") == 0
    assert dev.upload(new) == UploadResult.OK and active_bytes(dev) == new


def test_a_chunk_landing_on_a_stopped_table_drops_it():
    """The price of 32 KB in 48 KB: an upload over a stopped table larger than the arena
    leaves room for displaces it at its first chunk, so an upload abandoned there leaves
    no table (the CM-530 still has the old one in flash for the next start)."""
    capacity, arena = CM530
    dev = Device(capacity, arena)
    assert dev.upload(table_of(capacity).encode()) == UploadResult.OK
    new = table_of(capacity, seed=3).encode()
    writes = chunk_writes(new)
    assert dev.one(write(CTL_ID, *writes[0])).error == 0
    assert dev.get("Table Size") == 0 and dev.get("Table CRC") == 0 and active_bytes(dev) == b""
    assert dev.command("PLAY") == 0 and dev.state == State.IDLE  # refused: no table
    for address, payload in writes[1:]:
        assert dev.one(write(CTL_ID, address, payload)).error == 0
    assert dev.commit(len(new), zlib.crc32(new)) == 0
    assert dev.get("Upload Result") == UploadResult.OK and active_bytes(dev) == new


def test_a_repeated_commit_of_a_table_the_copy_overlapped_is_refused_harmlessly():
    capacity, arena = CM530
    dev = Device(capacity, arena)
    data = table_of(capacity).encode()
    assert dev.upload(data) == UploadResult.OK
    assert dev.commit(len(data), zlib.crc32(data)) == 0
    assert dev.get("Upload Result") == UploadResult.INCOMPLETE
    assert active_bytes(dev) == data and dev.get("Table Size") == len(data)


@pytest.mark.parametrize("size", [1024, 2048])
def test_on_the_qemu_board_an_upload_never_touches_the_playing_table(size):
    capacity, arena = QEMU
    dev = Device(capacity, arena)
    playing = table_of(capacity)
    assert dev.upload(playing.encode()) == UploadResult.OK
    assert dev.command("PLAY") == 0
    new = table_of(size, seed=4).encode()
    dev.upload(new, commit=False)  # every chunk WRITE answered without error
    assert dev.state == State.PLAYING
    last = playing.frame_count - 1
    assert play_to(dev, last) == frame_goals(playing, last)
    assert dev.commit(len(new), zlib.crc32(new)) == 0
    assert active_bytes(dev) == new
