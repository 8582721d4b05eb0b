"""The core's adaptive methods, Dormand-Prince 5(4) and 8(5,3) as it runs them (PI step
control, the inputs' phase taken from a per-step table; DOP853 on the trident with its
velocity inlined, in both input forms), meet their tolerance on a motion with a
closed-form solution, the higher order with fewer evaluations; and the batch entry point
gives exactly what one call per schedule gives."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snakebot.core import lib
from snakebot.model.kinematics import (
    Inputs,
    KinematicsError,
    Options,
    Sines,
    integrate_joints,
    integrate_joints_batch,
)
from snakebot.model.kinematics.integrate import integrate_fields
from snakebot.model.robots import load_robot

TRIDENT, SNAKE3, SNAKE5 = load_robot("trident"), load_robot("snake3"), load_robot("snake5")
C, A, OMEGA = 0.4, 1.5, 2 * math.pi  # u1(t) = C + A sin(omega t), u2 = u3 = 0
PHI0 = np.array([0.1, 0.2, -0.3])
SPAN = 10.0


def exact(t: np.ndarray) -> np.ndarray:
    """The trident driven forward along its body x axis at speed u1(t) (heading fixed):
    x = U(t), the integral of u1; each arm obeys nu' = (u1 / l) sin nu for its angle
    nu = alpha + phi, so tan(nu / 2) grows by exp(U / l)."""
    big_u = C * t + A / OMEGA * (1 - np.cos(OMEGA * t))
    alphas = np.array(TRIDENT.alphas)
    nu0 = alphas + PHI0
    nu = 2 * np.arctan(np.tan(nu0 / 2)[None, :] * np.exp(big_u / TRIDENT.l)[:, None])
    zeros = np.zeros_like(t)
    return np.column_stack((big_u, zeros, zeros, nu - alphas))


def run(method: str, rtol: float, samples: int = 41, form: str = "body", turns: float = 0.0):
    """The motion from PHI0 plus ``turns`` whole turns of each arm; with the heading fixed
    at 0 the world-frame inputs are the body-frame ones."""
    return integrate_fields(
        TRIDENT,
        Inputs((C, 0.0, 0.0), (A, 0.0, 0.0), omega=OMEGA, form=form),
        SPAN,
        q0=np.concatenate(([0.0, 0.0, 0.0], PHI0 + 2 * math.pi * turns)),
        samples=samples,
        options=Options(method, rtol=rtol, atol=rtol / 100),
    )


@pytest.mark.parametrize(
    "method,form", [("dopri5", "body"), ("dop853", "body"), ("dop853", "world")]
)
@pytest.mark.parametrize("rtol", [1e-6, 1e-9, 1e-12])
def test_adaptive_methods_meet_their_tolerance_on_a_closed_form_motion(method, form, rtol):
    traj = run(method, rtol, form=form)
    want = exact(traj.t)
    scale = rtol * np.maximum(np.abs(want), 1.0)  # what the tolerance allows per state
    err = np.abs(traj.q - want)
    # global error after 10 periods: within a small multiple of the local tolerance,
    # and not met by luck: a run ten times looser is measurably worse
    assert (err <= 5 * scale).all(), f"error {err.max():.2e} at rtol {rtol:g}"
    if rtol > 1e-12:
        loose = run(method, rtol * 100, samples=2, form=form)
        assert np.abs(loose.q[-1] - want[-1]).max() > np.abs(traj.q[-1] - want[-1]).max()


def test_arm_angles_past_the_cores_own_sine_range_take_libms_sines():
    # 160000 turns: the arms' angles are past 2^19 pi / 2, where the core's block sine
    # hands over to libm, also inside the trident's inlined DOP853 step; the motion is
    # the same, shifted by the whole turns (to the rounding of angles near 1e6)
    turns = 160000
    traj = run("dop853", 1e-12, samples=11, turns=turns)
    assert np.abs(traj.q[0, 3:]).min() > 2**19 * math.pi / 2
    want = exact(traj.t)
    want[:, 3:] += 2 * math.pi * turns
    np.testing.assert_allclose(traj.q, want, rtol=0, atol=1e-6)


def test_the_eighth_order_method_needs_fewer_evaluations_for_the_same_error():
    # at a tight tolerance the order tells: DOP853 is at least as accurate with
    # little more than half of DOPRI5's evaluations (measured: 5x as accurate, 56%)
    low, high = run("dopri5", 1e-11, samples=2), run("dop853", 1e-11, samples=2)
    want = exact(np.array([SPAN]))[0]
    err_low, err_high = (np.abs(r.q[-1] - want).max() for r in (low, high))
    assert err_high <= err_low
    assert high.stats["evals"] < 0.65 * low.stats["evals"]


@pytest.mark.parametrize("method", ["dopri5", "dop853"])  # dop853 also stops at switches
def test_batch_is_one_call_per_schedule_bit_for_bit(method):
    gaits = [
        Sines.serpenoid(4, amp, 2 * math.pi * 0.5, delta)
        for amp in (0.2, 0.5, 0.8)
        for delta in (0.3, 1.0, 2.0)
    ]
    options = Options(method, rtol=1e-8, atol=1e-10)
    batch = integrate_joints_batch(SNAKE5, gaits, 5.0, samples=6, options=options)
    assert (batch.status == lib.KIN_OK).all()
    for k, gait in enumerate(gaits):
        single = integrate_joints(SNAKE5, gait, 5.0, samples=6, options=options)
        np.testing.assert_array_equal(batch.q[k], single.q)
        assert batch.evals[k] == single.stats["evals"]
        assert batch.min_rcond[k] == single.stats["min_rcond"] < 1.0
    np.testing.assert_array_equal(batch.t, single.t)


def test_a_failed_trajectory_does_not_stop_the_batch():
    # joint 1 runs through joint 2 with a velocity free-rolling wheels cannot follow
    from dataclasses import replace

    free = replace(SNAKE3, friction=replace(SNAKE3.friction, rolling=0.0, axle_nm=0.0))
    bad = Sines(0.0, (0.0, 0.0), (0.0, 0.0), (-0.2, 0.3), (1.0, 0.0))
    good = Sines.serpenoid(2, 0.5, math.pi, 1.0)
    batch = integrate_joints_batch(free, [good, bad, good], 1.0, options=Options("rk4", h=0.01))
    assert batch.status.tolist() == [lib.KIN_OK, lib.KIN_EINADMISSIBLE, lib.KIN_OK]
    assert np.isnan(batch.q[1]).all() and np.isfinite(batch.q[[0, 2]]).all()
    np.testing.assert_array_equal(batch.q[0], batch.q[2])
    assert "cannot follow" in batch.error(1) and batch.error(0) is None
    assert integrate_joints_batch(SNAKE3, [], 1.0).q.shape == (0, 2, 5)


def test_a_bad_shared_argument_is_refused():
    with pytest.raises(KinematicsError, match="invalid argument"):
        integrate_joints_batch(SNAKE3, [Sines.serpenoid(2, 0.5, 1.0, 1.0)], 1.0, t0=2.0)


@pytest.mark.parametrize("method", ["dopri5", "dop853"])
def test_tables_that_differ_from_a_row_on_are_bit_for_bit_their_own_calls(method):
    """A batch of tables that agree with the first one up to some row (a tick search's
    trials, one frame changed each) continues each from the first one's state at the
    knot before that row: the same numbers and counters as one call per table (dop853's
    search for switches too starts afresh at each knot)."""
    from dataclasses import replace

    from snakebot.model.kinematics import Table
    from snakebot.model.plan.loops import SOLVE_OPTIONS, loop_angles

    options = replace(SOLVE_OPTIONS, method=method)

    hub = np.array([0.3, -0.2, 0.4, -0.1])
    coefficients = np.tile([0.3, 0.1, -0.2, 0.05], 4)
    base = loop_angles(hub, coefficients)
    tables = [base.copy()]
    trials = ((12, 0, 0.01), (1, 2, -0.02), (12, 3, 0.01), (23, 1, 0.003), (24, 2, 0.01))
    for row, joint, step in (*trials, (7, 0, 0.0)):
        changed = base.copy()
        changed[row, joint] += step
        tables.append(changed)
    tables[0][10, 1] += 0.01  # the first differs from the rest from row 10 on
    rows = float(len(base) - 1)
    schedules = [Table(t, 1.0) for t in tables]
    batch = integrate_joints_batch(SNAKE5, schedules, rows, options=options)
    assert (batch.status == lib.KIN_OK).all()
    for k, schedule in enumerate(schedules):
        single = integrate_joints(SNAKE5, schedule, rows, samples=2, options=options)
        np.testing.assert_array_equal(batch.q[k], single.q)
        assert batch.evals[k] == single.stats["evals"]
        assert batch.min_rcond[k] == single.stats["min_rcond"]
    # and they are different motions: the continued ones did not copy the first's end
    assert len({tuple(q[-1, :3]) for q in batch.q}) > 2
