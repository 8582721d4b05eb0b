"""Live serpenoid changes are slewed (firmware/core/play_slew.h): register changes made
while the wave runs reach the goals without any goal stepping further in one control
tick than the servo covers at its top speed, and the working copies reach the targets."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from player_support import SPEED_MAX, TICKS_PER_RAD, UNITS_PER_TICK_S, Player

from snakebot.core import ffi, lib

# The servo's top speed in ticks per second, from the AX-12A's description.
TOP_TICKS_S = SPEED_MAX / UNITS_PER_TICK_S
FIELDS = ("amp_mrad", "phi0_mrad", "steering", "omega_mrad_s", "speed_scale")

ROSTER = [  # id, reverse, zero, min, max
    (1, 0, 512, 0, 1023),
    (2, 1, 500, 0, 1023),
    (3, 0, 530, 0, 1023),
    (4, 1, 512, 0, 1023),
    (5, 0, 512, 0, 1023),
]


def wave_ticks_s(amp: int, omega: int, scale: int) -> float:
    """Peak goal speed of the wave alone, ticks/s."""
    return amp / 1000 * abs(omega) / 1000 * scale / 256 * TICKS_PER_RAD


def test_step_bound_is_the_servos_top_speed():
    for dt in (1, 7, 10, 20, 100, 1000):
        assert lib.play_slew_step_bound(dt) == math.floor(TOP_TICKS_S * dt / 1000 + 1e-9)


# A parameter set whose wave the servo follows with room to spare: the on-board
# validation refuses faster waves, and the bound cannot hold for them.
params = st.fixed_dictionaries(
    {
        "amp_mrad": st.integers(0, 1200),
        "phi0_mrad": st.integers(-1500, 1500),
        "steering": st.integers(-300, 300),
        "omega_mrad_s": st.integers(-6000, 6000),
        "speed_scale": st.integers(1, 512),
    }
)


def _fastest(sets: list[dict[str, int]]) -> float:
    # while slewing, the wave's speed stays below the larger of the old and the new one
    return max(wave_ticks_s(s["amp_mrad"], s["omega_mrad_s"], s["speed_scale"]) for s in sets)


@settings(max_examples=60, deadline=None)
@given(
    start=params,
    changes=st.lists(
        st.tuples(params, st.lists(st.integers(5, 40), min_size=1, max_size=30)),
        min_size=1,
        max_size=4,
    ),
    delta=st.integers(-3142, 3142),
)
def test_goals_never_step_beyond_the_servo_and_targets_are_reached(start, changes, delta):
    sets = [start] + [c[0] for c in changes]
    # dt >= 5 ms: the bound is >= 11 ticks; half the top speed leaves room for the slews
    assume(_fastest(sets) <= TOP_TICKS_S / 2)
    p = Player(ROSTER)
    for name, value in start.items():
        setattr(p.params, name, value)
    p.params.delta_mrad = delta
    now = 0
    assert p.start_serpenoid(len(ROSTER), now)
    last = p.tick(now)[1]
    for target, dts in changes:
        for name, value in target.items():
            setattr(p.params, name, value)  # a register write mid-run
        for dt in dts:
            now += dt
            goals = p.tick(now)[1]
            bound = lib.play_slew_step_bound(dt)
            assert max(abs(goals - last)) <= bound, (dt, goals - last, bound)
            last = goals
    # then 10 ms ticks until it settles: the goals become the targets' serpenoid
    for _ in range(1000):
        now += 10
        goals = p.tick(now)[1]
        assert max(abs(goals - last)) <= lib.play_slew_step_bound(10)
        last = goals
    assert _fits_some_phase(last, changes[-1][0], delta)


def _fits_some_phase(goals, final: dict[str, int], delta: int) -> bool:
    """Whether the goals are the final parameters' serpenoid at some phase: the amplitude,
    offset and steering all reached their targets (a 20000-step phase grid is finer than
    0.04 tick)."""
    phase = np.linspace(0, 2 * np.pi, 20_000, endpoint=False)[:, None]
    k = np.arange(len(ROSTER))
    rev = np.array([r[1] for r in ROSTER])
    zero = np.array([r[2] for r in ROSTER])
    sign = np.where(rev == 1, -1, 1)
    angle = final["amp_mrad"] / 1000 * np.sin(phase + k * delta / 1000) + final["phi0_mrad"] / 1000
    exact = np.clip(zero + sign * (angle * TICKS_PER_RAD + final["steering"]), 0, 1023)
    return bool(np.abs(exact - goals).max(axis=1).min() <= 0.6)


def _slew(**values: int):
    s = ffi.new("play_slew *")
    for name, value in values.items():
        setattr(s, name, value)
    return s


@settings(max_examples=200, deadline=None)
@given(start=params, target=params, dt=st.integers(1, 50))
def test_working_copies_reach_any_target(start, target, dt):
    s = _slew(**start)
    lib.play_slew_reset(s)
    assert lib.play_slew_toward(s, _slew(**start), dt) == 0  # a fresh start adopts at once
    assert all(getattr(s, f) == start[f] for f in FIELDS)
    goal = _slew(**target)
    for _ in range(20_000):
        lib.play_slew_toward(s, goal, dt)
        if all(getattr(s, f) == target[f] for f in FIELDS):
            break
    assert all(getattr(s, f) == target[f] for f in FIELDS)
    assert lib.play_slew_toward(s, goal, dt) == 0  # settled: no extra goal speed


def test_a_speed_change_does_not_jump_the_phase():
    # omega doubles mid-run: the goal keeps moving continuously, by no more than the
    # wave moves in one tick plus a tick of rounding
    p = Player(ROSTER[:1])
    p.params.amp_mrad, p.params.omega_mrad_s = 800, 2000
    p.start_serpenoid(1, 0)
    last = p.tick(0)[1]
    for now in range(10, 5000, 10):
        if now == 1230:
            p.params.omega_mrad_s = 4000
        goals = p.tick(now)[1]
        assert abs(goals[0] - last[0]) <= wave_ticks_s(800, 4000, 256) * 0.010 + 1
        last = goals


def test_a_large_phi0_step_is_spread_over_ticks():
    p = Player(ROSTER)
    p.params.amp_mrad, p.params.omega_mrad_s, p.params.delta_mrad = 500, 1000, 1000
    p.start_serpenoid(len(ROSTER), 0)
    last = p.tick(0)[1]
    p.params.phi0_mrad = 1200  # 234 ticks at once would be a jump of ten ticks' worth
    steps = []
    for now in range(10, 1000, 10):
        goals = p.tick(now)[1]
        steps.append(max(abs(goals - last)))
        last = goals
    bound = lib.play_slew_step_bound(10)
    assert max(steps) <= bound
    assert sum(s >= bound - 3 for s in steps) >= 5  # it moved at about the servo's pace


@settings(max_examples=200, deadline=None)
@given(start=params, target=params, dt=st.integers(1, 50))
def test_the_wave_speed_never_passes_above_both_ends(start, target, dt):
    # e.g. omega falling while the scale rises: each ramping alone would pass through
    # the old omega at the new scale, faster than either end
    s = _slew(**start)
    lib.play_slew_reset(s)
    lib.play_slew_toward(s, s, dt)
    goal = _slew(**target)
    ends = max(
        wave_ticks_s(p["amp_mrad"], p["omega_mrad_s"], p["speed_scale"]) for p in (start, target)
    )
    for _ in range(20_000):
        lib.play_slew_toward(s, goal, dt)
        assert wave_ticks_s(s.amp_mrad, s.omega_mrad_s, s.speed_scale) <= ends + 1e-9
        if all(getattr(s, f) == target[f] for f in FIELDS):
            break
    assert all(getattr(s, f) == target[f] for f in FIELDS)
