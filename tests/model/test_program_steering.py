"""Live steering of a running program (protocol/program.md, "Live steering"): the speed
scale runs the program's time, the steering offset applies to serpenoid segments only,
both slewed as the plain serpenoid's; the controller's player (C core, program mode)
sends, tick by tick, what the host's reference (``live_ticks``) says, within one tick,
with the registers changed mid-segment."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from snakebot.core import ffi, lib
from snakebot.formats.program import JointRecord, PeriodicSegment, Program, SerpenoidSegment
from snakebot.model.program_goals import live_ticks

JOINTS = tuple(JointRecord(k + 1, 512, 100, 924, k % 2 == 1) for k in range(4))
BLOCK = ((40, 250, 0), (0, 0, 250), (-40, 250, 0), (0, 120, 120))
PROGRAM = Program(
    10,
    JOINTS,
    (
        PeriodicSegment(0, 3000, 80),
        SerpenoidSegment(400, 3000, 1000, 0, 150),
        PeriodicSegment(0, -3000, 60),
        SerpenoidSegment(300, -2500, 900, 0, 120),
    ),
    (BLOCK,),
)


def c_ticks(program: Program, schedule: list[tuple[int, int, int]]) -> np.ndarray:
    """The goals the controller's player sends at each tick of ``schedule`` (dt,
    speed scale, steering), the program started at the first."""
    blob = ffi.new("uint8_t[]", program.encode())
    mem = ffi.new("uint8_t[]", lib.play_state_size())
    state = ffi.cast("play_state *", mem)
    params = ffi.new("play_params *")
    roster = ffi.new("play_joint[]", 1)
    lib.play_init(state)
    lib.play_start_program(state, blob, 0)
    now, out = 0, []
    for dt, scale, steering in schedule:
        now += dt
        params.speed_scale, params.steering = scale, steering
        lib.play_tick(state, params, roster, 0, now)  # after the end: the last goals stay
        out.append([lib.play_out_goal(state, j) for j in range(program.joint_count)])
    return np.array(out)


def run(schedule: list[tuple[int, int, int]]) -> tuple[np.ndarray, np.ndarray]:
    return c_ticks(PROGRAM, schedule), live_ticks(PROGRAM, schedule)


def test_steering_changed_mid_segment_matches_the_reference_tick_by_tick() -> None:
    # straight into the first serpenoid (steps 80..230), then steer left in it, slow
    # down, speed up and steer right: the periodic segment (steps 230..290, ticks about
    # 259..298) and the second serpenoid (to step 410, past tick 370) follow
    schedule = [(0, 256, 0)] + [(10, 256, 0)] * 100
    schedule += [(10, 256, 60)] * 60 + [(10, 128, 60)] * 80 + [(10, 400, -40)] * 130
    got, expected = run(schedule)
    assert np.abs(got - expected).max() <= 1
    sign = np.array([j.sign for j in JOINTS])
    unsteered = live_ticks(PROGRAM, [(d, s, 0) for d, s, _ in schedule])
    offset = (got - unsteered) * sign
    # the steering comes into the goals slewed, not at once, and then holds
    assert (offset[101] < 60).all() and (offset[101] > 0).all()
    assert (np.abs(offset[130:240] - 60) <= 1).all()
    # the periodic segment runs unsteered (slewed out first), the serpenoid after it
    # steered the other way
    assert (np.abs(offset[280:295]) <= 1).all()
    assert (np.abs(offset[330:370] + 40) <= 1).all()


def test_steering_does_not_reach_periodic_segments() -> None:
    schedule = [(0, 256, 0)] + [(10, 256, 80)] * 70  # inside the first, periodic segment
    got, expected = run(schedule)
    straight = live_ticks(PROGRAM, [(d, s, 0) for d, s, _ in schedule])
    assert np.array_equal(expected, straight)
    assert np.abs(got - straight).max() <= 1


@pytest.mark.parametrize("scale", [64, 256, 700])
def test_speed_scale_runs_the_program_in_scaled_time(scale: int) -> None:
    ticks = 60
    got, expected = run([(0, scale, 0)] + [(10, scale, 0)] * ticks)
    assert np.abs(got - expected).max() <= 1
    # the program has reached the step its scaled time says (a periodic segment: every
    # step differs in some joint, so the goals tell the step)
    plain = live_ticks(PROGRAM, [(0, 256, 0)] + [(10, 256, 0)] * 200)
    reached = ticks * 10 * scale // (256 * 10)
    assert np.abs(plain[reached] - got[-1]).max() <= 1


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(1, 40), st.integers(32, 800), st.integers(-120, 120)),
        min_size=1,
        max_size=12,
    ),
    st.integers(5, 60),
)
def test_any_register_changes_match_the_reference(
    changes: list[tuple[int, int, int]], hold: int
) -> None:
    schedule = [(0, 256, 0)]
    for dt, scale, steering in changes:
        schedule += [(dt, scale, steering)] * hold
    got, expected = run(schedule)
    assert np.abs(got - expected).max() <= 1
