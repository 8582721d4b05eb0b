"""The fixed-point serpenoid against the float formula
phi_k(t) = A sin(omega t + k delta) + phi0 (docs/models.md), in ticks."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from player_support import (
    TICKS_PER_RAD,
    UNITS_PER_TICK_S,
    Player,
    serpenoid_reference,
)

from snakebot.core import lib

TURN = 2**32
# The documented bound (firmware/core/play_fixed.h): within 0.53 tick of the exact value.
SERP_BOUND = 0.53


def test_sine_table_accuracy_over_a_dense_grid():
    angles = np.linspace(0, TURN - 1, 300_001).astype(np.uint64)
    got = np.array([lib.play_sin_q15(int(a)) for a in angles])
    exact = 32767 * np.sin(angles * 2 * np.pi / TURN)
    assert np.abs(got - exact).max() <= 1.5
    # symmetry: quadrant boundaries are exact
    assert [lib.play_sin_q15(q * TURN // 4) for q in range(4)] == [0, 32767, 0, -32767]


def test_mrad_to_binary_angle():
    for mrad in (0, 1, 1571, 3142, -1571, 6283, -6283, 31416):
        want = round(mrad / 1000 / (2 * math.pi) * TURN) % TURN
        got = lib.play_mrad_to_bam(mrad)
        assert min((got - want) % TURN, (want - got) % TURN) <= 1


@given(st.integers(0, 2618), st.integers(-2618, 2618), st.integers(0, TURN - 1))
def test_serpenoid_ticks_within_the_stated_bound(amp, phi0, theta):
    got = lib.play_serp_ticks(amp, phi0, theta)
    exact = serpenoid_reference(amp / 1000, theta * 2 * math.pi / TURN, 0, phi0 / 1000, 0)
    assert abs(got - exact) <= SERP_BOUND


def test_serpenoid_ticks_are_the_rounded_value_almost_always():
    rng = np.random.default_rng(5)
    amp = rng.integers(0, 2619, 20_000)
    phi0 = rng.integers(-2618, 2619, 20_000)
    theta = rng.integers(0, TURN, 20_000)
    got = np.array(
        [
            lib.play_serp_ticks(int(a), int(p), int(t))
            for a, p, t in zip(amp, phi0, theta, strict=True)
        ]
    )
    exact = (amp / 1000 * np.sin(theta * 2 * np.pi / TURN) + phi0 / 1000) * TICKS_PER_RAD
    assert np.abs(got - exact).max() <= SERP_BOUND
    assert np.mean(got == np.floor(exact + 0.5)) > 0.97


ROSTER = [  # id, reverse, zero, min, max
    (10, 0, 512, 0, 1023),
    (11, 1, 500, 0, 1023),
    (15, 0, 530, 0, 1023),
    (16, 1, 512, 0, 1023),
    (17, 0, 512, 0, 1023),
]


@given(
    amp=st.integers(0, 1500),
    omega=st.integers(-31416, 31416),
    delta=st.integers(-6283, 6283),
    phi0=st.integers(-600, 600),
    scale=st.integers(1, 1024),
    steps=st.lists(st.integers(0, 200), min_size=1, max_size=40),
)
def test_player_serpenoid_follows_the_formula(amp, omega, delta, phi0, scale, steps):
    p = Player(ROSTER)
    p.params.amp_mrad, p.params.omega_mrad_s = amp, omega
    p.params.delta_mrad, p.params.phi0_mrad = delta, phi0
    p.params.speed_scale = scale
    assert p.start_serpenoid(len(ROSTER), now=50)
    now, t = 50, 0.0
    for dt in steps:
        now += dt
        t += dt / 1000 * scale / 256
        ids, goals, speeds = p.tick(now)
        assert list(ids) == [r[0] for r in ROSTER]
        for k, (_, rev, zero, _, _) in enumerate(ROSTER):
            phase = omega / 1000 * t
            offset = serpenoid_reference(amp / 1000, phase, delta / 1000, phi0 / 1000, k)
            exact = zero + (-offset if rev else offset)
            assert abs(goals[k] - exact) <= SERP_BOUND + 1e-6, (k, goals[k], exact)
            rate = (
                amp
                / 1000
                * abs(omega)
                / 1000
                * scale
                / 256
                * abs(math.cos(phase + k * delta / 1000))
                * TICKS_PER_RAD
            )
            ref = min(max(math.ceil(rate * UNITS_PER_TICK_S), 16), 1023)
            assert abs(speeds[k] - ref) <= 1


def test_steering_changes_while_it_moves_and_clamps():
    roster = [(1, 0, 512, 300, 700), (2, 1, 512, 300, 700)]
    p = Player(roster)
    # omega 0: the wave stands still, so only phi0 moves the goals
    p.params.amp_mrad, p.params.omega_mrad_s, p.params.delta_mrad = 300, 0, 1571
    p.start_serpenoid(2)
    before = p.tick(100)[1]
    p.params.phi0_mrad = 500  # steer: +97.7 ticks on joint 1, -97.7 on the reversed joint 2
    assert list(p.tick(100)[1]) == list(before)  # no time passed: slewed, not stepped
    after = [p.tick(now)[1] for now in range(110, 1000, 10)][-1]
    assert after[0] - before[0] in (97, 98, 99) and before[1] - after[1] in (97, 98, 99)
    p.params.phi0_mrad = 2000  # far past the limits
    assert list(p.tick(3000)[1]) == [700, 300]


def test_serpenoid_needs_joints():
    p = Player()
    assert not p.start_serpenoid(0)
    assert not p.start_serpenoid(lib.CTL_MAX_JOINTS + 1)
    assert p.mode == lib.PLAY_MODE_IDLE


def test_phase_stays_exact_over_a_long_run():
    # the phase is accumulated tick by tick, not recomputed: one hour of 1 s ticks
    # (PLAY_MAX_STEP_MS) must not drift
    p = Player([(1, 0, 512, 0, 1023)])
    p.params.amp_mrad, p.params.omega_mrad_s = 1000, 2513  # 0.4 Hz
    p.start_serpenoid(1, now=0)
    for now in range(1000, 3_600_001, 1000):
        goals = p.tick(now)[1]
    exact = 512 + serpenoid_reference(1.0, 2.513 * 3600, 0, 0, 0)
    assert abs(goals[0] - exact) <= SERP_BOUND
