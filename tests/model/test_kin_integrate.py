"""Whole-trajectory integration in the C core: RK4 against Dormand-Prince 5(4), the
3-link snake through its singular line against a high-accuracy reference, periodic
inputs against the bracket prediction, and the serpenoid with delta = pi."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from snakebot.core import lib
from snakebot.model.kinematics import (
    Inputs,
    KinematicsError,
    Options,
    Sines,
    Table,
    field_velocity,
    fields,
    integrate_fields,
    integrate_joints,
    schedule_eval,
    wheel_speeds,
)
from snakebot.model.kinematics.ccore import c_robot
from snakebot.model.robots import load_robot

SNAKE3, SNAKE5, TRIDENT = load_robot("snake3"), load_robot("snake5"), load_robot("trident")
#: Free-rolling wheels (no rolling resistance): the pure non-slip model, singular where
#: the axles meet (the 3-link snake's phi1 = phi2).
FREE = replace(SNAKE3.friction, rolling=0.0, axle_nm=0.0)
SNAKE3_FREE = replace(SNAKE3, friction=FREE)
FINE = Options("dopri5", rtol=1e-11, atol=1e-13)
Q0_SNAKE3 = np.array([0, 0, 0, math.pi / 3, -math.pi / 3])


def loop_inputs(i, j, amplitude, omega, m=3, form=None):
    """u_i = -A w sin(w t), u_j = A w cos(w t): moves +pi A^2 [g_i, g_j] per period."""
    a, b = [0.0] * m, [0.0] * m
    a[i], b[j] = -amplitude * omega, amplitude * omega
    return Inputs((0.0,) * m, tuple(a), tuple(b), omega, form)


def test_adaptive_agrees_with_fine_rk4_trident_periodic_inputs():
    inputs = loop_inputs(0, 2, 0.3, 2.0)
    adaptive = integrate_fields(TRIDENT, inputs, 10.0, samples=11, options=FINE)
    rk4 = integrate_fields(TRIDENT, inputs, 10.0, samples=11, options=Options("rk4", h=1e-3))
    np.testing.assert_allclose(adaptive.q, rk4.q, atol=1e-9)
    assert adaptive.stats["steps"] < rk4.stats["steps"] / 5


def test_adaptive_agrees_with_fine_rk4_five_link_serpenoid():
    gait = Sines.serpenoid(4, 0.5, 2 * math.pi, math.pi / 2)
    adaptive = integrate_joints(SNAKE5, gait, 3.0, samples=7, options=FINE)
    rk4 = integrate_joints(SNAKE5, gait, 3.0, samples=7, options=Options("rk4", h=5e-4))
    # Five wheels: the body velocity switches which wheels stick (a kink in the right-hand
    # side), so a fixed step is first order there; the adaptive method steps onto kinks.
    np.testing.assert_allclose(adaptive.q, rk4.q, atol=1e-5)
    finer = integrate_joints(SNAKE5, gait, 3.0, samples=7, options=Options("rk4", h=2.5e-4))
    assert np.abs(finer.q - adaptive.q).max() < np.abs(rk4.q - adaptive.q).max()


def test_dop853_ends_its_steps_at_the_switches_between_sticking_and_slipping():
    # Five wheels: a few times a second the wheels that stick change, and the body
    # velocity has a kink or a jump there. DOP853 ends a step just before each switch
    # and starts the next just after, so its error stays at its tolerance; DOPRI5 steps
    # across them (rejecting step after step) and misses its tolerance by far.
    gait = Sines.serpenoid(4, 0.5, math.pi, math.pi / 2)
    reference = integrate_joints(SNAKE5, gait, 4.0, options=FINE).q[-1, :3]
    errors, stats = {}, {}
    for method in ("dopri5", "dop853"):
        run = integrate_joints(SNAKE5, gait, 4.0, options=Options(method, rtol=1e-8, atol=1e-10))
        errors[method] = np.abs(run.q[-1, :3] - reference).max()
        stats[method] = run.stats
    assert errors["dop853"] < 1e-9 < 1e-7 < errors["dopri5"]
    assert stats["dop853"]["rejected"] < stats["dop853"]["steps"] / 4
    assert stats["dopri5"]["rejected"] > stats["dopri5"]["steps"] / 2
    assert stats["dop853"]["evals"] < stats["dopri5"]["evals"]


def test_rk4_converges_at_fourth_order():
    inputs = loop_inputs(0, 1, 0.5, 3.0)
    exact = integrate_fields(TRIDENT, inputs, 2.0, options=FINE).q[-1]
    errors = [
        np.abs(
            integrate_fields(TRIDENT, inputs, 2.0, options=Options("rk4", h=h)).q[-1] - exact
        ).max()
        for h in (0.02, 0.01)
    ]
    assert 12 < errors[0] / errors[1] < 20


def _reference_snake3_serpenoid(amplitude, omega, delta, t_end):
    """scipy DOP853 on models.md's B^-1 C formulation (numpy), tight tolerances."""

    def rhs(t, y):
        p1, p2 = (amplitude * np.sin(omega * t + k * delta) for k in (0, 1))
        u = np.array([amplitude * omega * np.cos(omega * t + k * delta) for k in (0, 1)])
        s12, c12 = np.sin(p1 + p2), np.cos(p1 + p2)
        b = np.array(
            [
                [0, 1, 1],
                [-np.sin(p1), np.cos(p1), 1 + 2 * np.cos(p1)],
                [-s12, c12, 1 + 2 * np.cos(p2) + 2 * c12],
            ]
        )
        c = np.array([[0, 0], [1, 0], [1 + 2 * np.cos(p2), 1]])
        xb, yb, w = -np.linalg.solve(b, c @ u)
        return [np.cos(y[2]) * xb - np.sin(y[2]) * yb, np.sin(y[2]) * xb + np.cos(y[2]) * yb, w]

    sol = solve_ivp(rhs, (0, t_end), [0.0, 0.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-14)
    assert sol.success
    return sol.y[:, -1]


def test_snake3_serpenoid_crosses_the_singular_line_accurately():
    # phi1 - phi2 = A (sin wt - sin(wt + pi/2)) vanishes at wt = pi/4 + k pi: four crossings
    # in two periods, each with the admissible joint velocity (1, -1).
    amplitude, omega, delta = 1.0, 2.0, math.pi / 2
    t_end = 2 * (2 * math.pi / omega)
    reference = _reference_snake3_serpenoid(amplitude, omega, delta, t_end)
    gait = Sines.serpenoid(2, amplitude, omega, delta)
    adaptive = integrate_joints(SNAKE3_FREE, gait, t_end, options=Options("dopri5", 1e-12, 1e-13))
    np.testing.assert_allclose(adaptive.q[-1, :3], reference, atol=1e-8)
    # RK4 whose grid lands exactly on every crossing (t = T/8 + k T/2): det B = 0 there.
    rk4 = integrate_joints(SNAKE3_FREE, gait, t_end, options=Options("rk4", h=t_end / 1600))
    assert rk4.stats["fallbacks"] >= 4
    assert rk4.stats["min_rcond"] < 1e-12
    np.testing.assert_allclose(rk4.q[-1, :3], reference, atol=1e-8)
    assert abs(reference[0]) > 1  # it does move


@pytest.mark.parametrize(
    "robot,friction", [(SNAKE3, None), (SNAKE5, None), (SNAKE5, replace(FREE, lateral=0.5))]
)
def test_serpenoid_with_delta_pi_goes_nowhere(robot, friction):
    omega = 3.0
    gait = Sines.serpenoid(robot.n_joints, 0.6, omega, math.pi)
    traj = integrate_joints(
        robot, gait, 2 * (2 * math.pi / omega), samples=3, options=FINE, friction=friction
    )
    assert np.abs(traj.q[-1, :3]).max() < 1e-9
    moving = integrate_joints(
        robot,
        Sines.serpenoid(robot.n_joints, 0.6, omega, 2.0),
        2 * (2 * math.pi / omega),
        options=FINE,
        friction=friction,
    )
    assert np.abs(moving.q[-1, :2]).max() > 1e-3 * robot.l


@pytest.mark.parametrize(
    "robot,pair,name,form",
    [
        (TRIDENT, (0, 1), "h1", "body"),
        (TRIDENT, (0, 2), "h2", "body"),
        (TRIDENT, (1, 2), "h3", "body"),
        (TRIDENT, (0, 2), "h2", "world"),
        (SNAKE3, (0, 1), "h1", None),
    ],
)
def test_periodic_inputs_converge_to_the_bracket_linearly_in_a(robot, pair, name, form):
    q0 = Q0_SNAKE3 if robot is SNAKE3 else np.array([0.2, -0.1, 0.4, 0.3, -0.2, 0.1])
    m = 2 if robot is SNAKE3 else 3
    bracket = fields(robot, q0, form)[name]
    errors = []
    for amplitude in (0.1, 0.05, 0.025):
        omega = 2.0
        traj = integrate_fields(
            robot,
            loop_inputs(*pair, amplitude, omega, m, form),
            2 * math.pi / omega,
            q0=q0,
            options=FINE,
        )
        predicted = math.pi * amplitude**2 * bracket
        errors.append(np.linalg.norm(traj.displacement - predicted) / np.linalg.norm(predicted))
    assert errors[-1] < 0.05
    for big, small in zip(errors, errors[1:], strict=False):
        assert 1.6 < big / small < 2.5  # halving A halves the relative error


def test_third_order_loops_move_along_the_snake3_double_brackets():
    # u_i = A cos t, u_j = 2 B cos 2t moves -(pi A^2 B / 2) [g_i, [g_i, g_j]] per period.
    f = fields(SNAKE3, Q0_SNAKE3)
    for name, b, b2, sign in (("h2", (1, 0), (0, -2), 1.0), ("h3", (0, 1), (2, 0), 1.0)):
        errors = []
        for a in (0.1, 0.05):
            inputs = Inputs(
                (0.0, 0.0), b=tuple(a * v for v in b), b2=tuple(a * v for v in b2), omega=1.0
            )
            moved = integrate_fields(
                SNAKE3, inputs, 2 * math.pi, q0=Q0_SNAKE3, options=FINE
            ).displacement
            predicted = sign * math.pi * a**3 / 2 * f[name]
            errors.append(np.linalg.norm(moved - predicted) / np.linalg.norm(predicted))
        assert errors[1] < 0.002 and errors[0] / errors[1] > 3


@pytest.mark.parametrize("robot,form", [(TRIDENT, "body"), (TRIDENT, "world"), (SNAKE3, None)])
def test_fields_satisfy_the_constraints_along_random_trajectories(robot, form):
    rng = np.random.default_rng(11)
    m = 2 if robot is SNAKE3 else 3
    for _ in range(4):
        inputs = Inputs(
            tuple(rng.uniform(-0.3, 0.3, m)),
            tuple(rng.uniform(-0.5, 0.5, m)),
            tuple(rng.uniform(-0.5, 0.5, m)),
            float(rng.uniform(0.5, 3)),
            form,
        )
        q0 = Q0_SNAKE3 if robot is SNAKE3 else np.r_[rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)]
        traj = integrate_fields(robot, inputs, 1.0, q0=q0, samples=201, options=FINE)
        u = inputs.at(traj.t)
        qdot = np.array(
            [field_velocity(robot, q, uk, form) for q, uk in zip(traj.q, u, strict=True)]
        )
        for q, v in zip(traj.q, qdot, strict=True):
            normal, _ = wheel_speeds(robot, q, v)
            assert np.abs(normal).max() < 1e-9
        # and the trajectory does follow those velocities
        slope = (traj.q[2:] - traj.q[:-2]) / (2 * (traj.t[1] - traj.t[0]))
        np.testing.assert_allclose(slope, qdot[1:-1], atol=1e-3)


def test_field_and_joint_integrators_agree_for_snake3():
    # For the 3-link snake the inputs are the joint velocities, so the same motion can be
    # integrated as a joint schedule through the quasi-static model (no wheel slides there).
    c, a, b, omega = (0.05, -0.02), (0.3, -0.1), (0.2, 0.25), 1.7
    inputs = Inputs(c, a, b, omega)
    by_fields = integrate_fields(SNAKE3, inputs, 2.0, q0=Q0_SNAKE3, samples=5, options=FINE)
    offset = [Q0_SNAKE3[3 + k] + a[k] / omega for k in range(2)]
    amp = [math.hypot(a[k], b[k]) / omega for k in range(2)]
    phase = [math.atan2(-a[k], b[k]) for k in range(2)]
    schedule = Sines(omega, tuple(amp), tuple(phase), tuple(offset), c)
    by_joints = integrate_joints(SNAKE3, schedule, 2.0, samples=5, options=FINE)
    np.testing.assert_allclose(by_joints.q, by_fields.q, atol=1e-9)


def test_tables_interpolate_linearly_and_loops_wrap():
    samples = np.array([[0.0, 0.1], [0.2, -0.1], [0.4, 0.3]])
    table = Table(samples, 0.5, loop=True)
    for t, expected in (
        (0.25, [0.1, 0.0]),
        (0.75, [0.3, 0.1]),
        (1.25, [0.2, 0.2]),
        (1.5, [0.0, 0.1]),
        (-0.25, [0.2, 0.2]),
    ):
        phi, _ = schedule_eval(SNAKE3, table, t)
        np.testing.assert_allclose(phi, expected, atol=1e-12)
    _, dphi = schedule_eval(SNAKE3, table, 1.2)
    np.testing.assert_allclose(dphi, [-0.8, -0.4])
    once = Table(samples, 0.5, loop=False)
    phi, dphi = schedule_eval(SNAKE3, once, 3.0)
    assert phi.tolist() == [0.4, 0.3] and dphi.tolist() == [0.0, 0.0]


def test_finely_sampled_table_approaches_the_continuous_gait():
    gait = Sines.serpenoid(4, 0.5, 2 * math.pi, math.pi / 2)
    exact = integrate_joints(SNAKE5, gait, 1.0, options=FINE).q[-1]
    errors = []
    for dt in (0.02, 0.01):
        t = np.arange(round(1.0 / dt)) * dt
        samples = 0.5 * np.sin(2 * math.pi * t[:, None] + np.array(gait.phase))
        errors.append(
            np.abs(
                integrate_joints(SNAKE5, Table(samples, dt, loop=True), 1.0, options=FINE).q[-1]
                - exact
            ).max()
        )
    # first order: where the sticking wheels change, the table's kinks shift the switch
    assert errors[1] < errors[0] / 1.8


def test_inadmissible_crossing_is_reported():
    # phi1 runs through phi2 = 0.3 at t = 0.5 with joint velocity (1, 0): the 3-link
    # snake's body velocity has a pole there.
    schedule = Sines(0.0, (0.0, 0.0), (0.0, 0.0), (-0.2, 0.3), (1.0, 0.0))
    with pytest.raises(KinematicsError) as err:
        integrate_joints(SNAKE3_FREE, schedule, 1.0, options=Options("rk4", h=0.01))
    assert err.value.code == lib.KIN_EINADMISSIBLE and "t = 0.5" in str(err.value)
    with pytest.raises(KinematicsError):
        integrate_joints(SNAKE3_FREE, schedule, 1.0, options=FINE)
    # with rolling resistance the wheels slip instead
    traj = integrate_joints(SNAKE3, schedule, 1.0, samples=101, options=FINE, with_slip=True)
    assert np.isfinite(traj.q).all() and np.abs(traj.slip).max() > 1e-3


def test_snake3_field_flow_into_the_singular_line_is_an_error():
    with pytest.raises(KinematicsError, match="singular|step size"):
        integrate_fields(
            SNAKE3, Inputs((1.0, 0.0)), 3.0, q0=np.array([0, 0, 0, 0.0, 1.0]), options=FINE
        )


def test_bad_options_are_refused():
    with pytest.raises(KinematicsError, match="invalid argument"):
        integrate_fields(TRIDENT, Inputs((1, 0, 0)), 1.0, options=Options("rk4", h=0.0))
    with pytest.raises(KinematicsError, match="unknown method"):
        Options("euler").to_c()


def test_structs_reused_across_calls_follow_the_values_they_were_built_from():
    # The robot and input structs are cached by value: an equal robot with other friction,
    # or other inputs, must get its own; inputs in lists (unhashable) still work.
    inputs = loop_inputs(0, 1, 0.3, 2.0)
    first = integrate_fields(TRIDENT, inputs, 1.0).q[-1]
    as_lists = Inputs(list(inputs.c), list(inputs.a), list(inputs.b), inputs.omega)
    np.testing.assert_array_equal(integrate_fields(TRIDENT, as_lists, 1.0).q[-1], first)
    other = integrate_fields(TRIDENT, loop_inputs(0, 1, 0.2, 2.0), 1.0).q[-1]
    assert np.abs(other - first).max() > 1e-3
    gait = Sines.serpenoid(4, 0.5, math.pi, math.pi / 2)
    frictions = [replace(SNAKE5.friction, rolling=r) for r in (0.01, 0.5, 0.01)]
    slips = [integrate_joints(SNAKE5, gait, 2.0, friction=f).q[-1] for f in frictions]
    assert np.abs(slips[0] - slips[1]).max() > 1e-3
    np.testing.assert_array_equal(slips[0], slips[2])


def test_robot_structs_follow_each_robot_object():
    # Structs are found by the robot and friction objects' identity: robots made and
    # dropped one after another (more than the cache holds, so their ids come free for
    # reuse) each get their own values, and so does each friction.
    for k in range(100):
        robot = replace(TRIDENT, l=1.0 + k / 64)
        assert c_robot(robot).l == robot.l
        friction = replace(robot.friction, lateral=0.5 + k / 64)
        lateral, _ = robot.wheel_friction_n(friction)
        assert list(c_robot(robot, friction).lateral[0:3]) == list(lateral)
        assert c_robot(robot).lateral[0] == robot.wheel_friction_n()[0][0]
