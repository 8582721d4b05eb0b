"""The table player against a float (numpy) reference: interpolation, looping, playing
once, speed scale, clamping with steering, and moving speeds from the next frame."""

from __future__ import annotations

import numpy as np
from ctl_support import gait_tables
from hypothesis import given
from hypothesis import strategies as st
from player_support import Player, speed_reference, table_reference

from snakebot.core import lib
from snakebot.formats.gaittable import GaitTable


def ramp(loop: bool = True, period: int = 100) -> GaitTable:
    frames = np.array([[512, 300], [612, 320], [412, 300], [512, 1000]])
    return GaitTable((1, 2), period, loop, ((0, 1023), (0, 1023)), frames)


def test_hand_example():
    p = Player()
    assert p.start_table(ramp(), now=1000)
    ids, goals, speeds = p.tick(1000)
    assert list(ids) == [1, 2] and list(goals) == [512, 300]
    # 512 -> 612 over 100 ms = 1000 ticks/s = 440.3 units, rounded up
    assert list(speeds) == [441, 89]
    _, goals, _ = p.tick(1025)
    assert list(goals) == [537, 305]
    _, goals, _ = p.tick(1150)  # half-way from frame 1 to frame 2
    assert list(goals) == [512, 310]
    _, goals, _ = p.tick(1375)  # wraps from frame 3 back to frame 0 (loop)
    assert list(goals) == [512, 475]
    assert lib.play_frame_index(p.p) == 3


@given(
    gait_tables(max_joints=5),
    st.lists(st.integers(0, 400), min_size=1, max_size=60),
    st.integers(1, 1024),
)
def test_interpolation_equals_numpy_reference(table, steps, scale):
    p = Player()
    p.params.speed_scale = scale
    assert p.start_table(table, now=7)
    now, u = 7, 0.0
    for dt in steps:
        now += dt
        u += dt * scale / 256
        _, goals, _ = p.tick(now)
        ref = table_reference(table, u)
        # rounded to the nearest tick (halves up)
        assert np.all(np.abs(goals - ref) <= 0.5 + 1e-9), (goals, ref)
        if not table.loop and u >= (table.frame_count - 1) * table.frame_period_ms:
            assert p.mode == lib.PLAY_MODE_IDLE and lib.play_finished(p.p)
            assert np.array_equal(goals, table.frames[-1])
            break
        assert p.mode == lib.PLAY_MODE_TABLE


@given(gait_tables(max_joints=4, loop=True), st.integers(1, 1024), st.integers(0, 10_000))
def test_speeds_come_from_the_segment_being_played(table, scale, at):
    p = Player()
    p.params.speed_scale = scale
    p.start_table(table, now=0)
    now = 0
    while now < at:  # ticks of at most 1 s (longer gaps are capped)
        now = min(now + 1000, at)
        _, _, speeds = p.tick(now)
    _, _, speeds = p.tick(now)
    k = lib.play_frame_index(p.p)
    nxt = (k + 1) % table.frame_count
    step = np.abs(table.frames[nxt].astype(int) - table.frames[k].astype(int))
    rate = step * 1000 * scale / 256 / table.frame_period_ms
    ref = np.array([speed_reference(r) for r in rate])
    assert np.all(np.abs(speeds - ref) <= 1), (speeds, ref)


def test_speed_scale_plays_faster_and_slower():
    t = ramp()
    normal, fast = Player(), Player()
    fast.params.speed_scale = 512
    normal.start_table(t)
    fast.start_table(t)
    for ms in range(0, 210, 10):
        goals_fast = fast.tick(ms)[1]
        goals_normal = normal.tick(2 * ms)[1]
        assert np.array_equal(goals_fast, goals_normal)
    # and it can change while playing: 200 ms at half speed = 100 ms of table time
    fast.params.speed_scale = 128
    goals = fast.tick(400)[1]
    assert np.array_equal(goals, np.floor(table_reference(t, 500) + 0.5))


def test_steering_offset_is_added_and_clamped_to_the_table_limits():
    frames = np.array([[500, 500, 500], [520, 480, 990]])
    t = GaitTable((1, 2, 3), 50, True, ((480, 530), (450, 560), (0, 1000)), frames)
    p = Player(roster=[(1, 0, 512, 0, 1023), (2, 1, 512, 0, 1023), (3, 0, 512, 0, 1023)])
    p.params.steering = 20
    p.start_table(t)
    _, goals, _ = p.tick(0)
    assert list(goals) == [520, 480, 520]  # joint 2 is reversed: -20
    _, goals, _ = p.tick(50)
    assert list(goals) == [530, 460, 1000]  # 540 and 1010 clamped to the limits
    p.params.steering = -512
    _, goals, _ = p.tick(50)
    assert list(goals) == [480, 560, 478]


def test_once_holds_the_last_frame_and_stops():
    p = Player()
    t = ramp(loop=False)
    p.start_table(t)
    assert list(p.tick(299)[1]) == [511, 993]
    ids, goals, _ = p.tick(300)
    assert list(goals) == [512, 1000] and p.mode == lib.PLAY_MODE_IDLE
    assert lib.play_finished(p.p)
    assert p.tick(400)[0].size == 0  # idle: nothing more to send


def test_long_stall_does_not_jump_far_ahead():
    p = Player()
    t = ramp(period=1000)
    p.start_table(t)
    p.tick(0)
    p.tick(100_000)  # the loop stalled for 100 s: counts as PLAY_MAX_STEP_MS
    assert lib.play_frame_index(p.p) == lib.PLAY_MAX_STEP_MS // 1000


def test_an_invalid_table_is_not_played():
    p = Player()
    bad = bytearray(ramp().encode())
    bad[-1] ^= 1
    from snakebot.core import ffi

    buf = ffi.new("uint8_t[]", bytes(bad))
    assert not lib.play_start_table(p.p, buf, len(bad), 0)
    assert p.mode == lib.PLAY_MODE_IDLE
