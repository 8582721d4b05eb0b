"""The quasi-static Coulomb model of the wheels (docs/models.md, "The general model"):
the C core's exact L1 solve against an independent LP (scipy's HiGHS), the no-slip
fields it reduces to, and what it gives where those are undefined."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import linprog

from snakebot.model.gait.serpenoid import SerpenoidWave, serpenoid_frames
from snakebot.model.kinematics import (
    Options,
    SingularConfiguration,
    Table,
    body_velocity,
    fields,
    integrate_joints,
    quasi_static,
    quasi_static_path,
    wheel_speeds,
    wheels,
)
from snakebot.model.robots import load_robot

SNAKE3, SNAKE5, TRIDENT = load_robot("snake3"), load_robot("snake5"), load_robot("trident")
SNAKE4 = replace(SNAKE5, name="snake4", links=4, joints=SNAKE5.joints[:3])


def lp_minimum(robot, q: np.ndarray, dphi: np.ndarray) -> float:
    """min over xi of sum lateral |n.v| + rolling |t.v|, as a linear programme."""
    lateral, rolling = robot.wheel_friction_n()

    def speeds(xi: np.ndarray) -> np.ndarray:
        return np.concatenate(wheel_speeds(robot, q, np.concatenate((xi, dphi))))

    c0 = speeds(np.zeros(3))
    a = np.stack([speeds(e) - c0 for e in np.eye(3)], axis=1)
    w = np.concatenate((lateral, rolling))
    m = len(w)
    res = linprog(
        np.concatenate((np.zeros(3), w)),
        A_ub=np.block([[a, -np.eye(m)], [-a, -np.eye(m)]]),
        b_ub=np.concatenate((-c0, c0)),
        bounds=[(None, None)] * 3 + [(0, None)] * m,
        method="highs",
    )
    assert res.status == 0
    return float(res.fun)


def power(robot, q: np.ndarray, dphi: np.ndarray, xi: np.ndarray) -> float:
    lateral, rolling = robot.wheel_friction_n()
    n, t = wheel_speeds(robot, q, np.concatenate((xi, dphi)))
    return float(lateral @ np.abs(n) + rolling @ np.abs(t))


@pytest.mark.parametrize("robot", [SNAKE3, TRIDENT, SNAKE4, SNAKE5], ids=lambda r: r.name)
def test_body_velocity_is_the_least_dissipating_one(robot):
    rng = np.random.default_rng(7)
    for _ in range(40):
        q = np.concatenate((rng.normal(size=3), rng.uniform(-1.4, 1.4, robot.n_joints)))
        dphi = rng.normal(size=robot.n_joints)
        xi = body_velocity(robot, q, dphi).xi
        best = lp_minimum(robot, q, dphi)
        assert power(robot, q, dphi, xi) == pytest.approx(best, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize(
    "robot,q",
    [
        (SNAKE3, [0.3, -0.2, 0.5, math.pi / 3, -math.pi / 3]),
        (SNAKE3, [0, 0, 0, 0.9, -0.4]),
        (TRIDENT, [0.1, 0.2, 0.3, 0.2, -0.3, 0.4]),
    ],
    ids=["snake3-thesis-point", "snake3-bent", "trident"],
)
def test_away_from_singular_configurations_it_is_the_no_slip_model(robot, q):
    """With the wheels' constraints compatible, sticking costs nothing and rolling is
    cheap: the body moves exactly as the non-slip fields say, no wheel slides."""
    q = np.array(q, dtype=float)
    if robot.kind == "snake":
        g = fields(robot, q).values  # g1, g2: joint inputs
        for k in range(2):
            bv = body_velocity(robot, q, g[k, 3:])
            np.testing.assert_allclose(bv.xi, g[k, :3], atol=1e-12)
            np.testing.assert_allclose(bv.slip, 0.0, atol=1e-12)
    else:
        g = fields(robot, q, form="world").values  # planar inputs, joints follow
        for k in range(3):
            bv = body_velocity(robot, q, g[k, 3:])
            np.testing.assert_allclose(bv.xi, g[k, :3], atol=1e-12)


def test_at_the_singular_line_the_motion_is_defined_and_some_wheel_slides():
    """phi1 = phi2: the non-slip fields do not exist; the friction decides, finitely."""
    q = np.array([0, 0, 0, 0.4, 0.4])
    for dphi in ([1.0, 0.0], [0.0, 1.0], [1.0, 1.0]):
        bv = body_velocity(SNAKE3, q, np.array(dphi))
        assert np.isfinite(bv.xi).all()
        assert np.abs(bv.slip).max() > 1e-6
    # the admissible direction (1, -1) is still followed without slip
    assert np.abs(body_velocity(SNAKE3, q, np.array([1.0, -1.0])).slip).max() < 1e-12


def test_where_the_least_power_is_an_edge_the_motion_is_its_centre():
    """Four links on an arc, bending evenly: the axles meet in the arc's centre and the
    four equal rolling resistances balance, so the least power is a whole edge of body
    velocities (two wheels rolling one way and two the other, at any split). The model
    takes the edge's centre, where all four roll equally fast: the same answer whatever
    the heading (a solve reaching either end by rounding made it jump)."""
    bend, rate = 0.48685, 0.511827
    dphi = np.full(3, rate)
    rolled = []
    for heading in (0.0, 1e-9, 0.3, -2.0):
        q = np.array([0.1, -0.2, heading, bend, bend, bend])
        xi = body_velocity(SNAKE4, q, dphi).xi
        assert power(SNAKE4, q, dphi, xi) == pytest.approx(lp_minimum(SNAKE4, q, dphi), rel=1e-9)
        rolled.append(wheel_speeds(SNAKE4, q, np.concatenate((xi, dphi)))[1])
    speeds = np.abs(np.array(rolled))
    assert speeds.min() > 1e-3  # every wheel rolls (at an end of the edge two would not)
    np.testing.assert_allclose(speeds, speeds[0, 0], rtol=1e-9)


def test_the_joints_power_is_what_the_wheels_dissipate():
    rng = np.random.default_rng(3)
    for robot in (SNAKE3, SNAKE5, TRIDENT):
        q = np.concatenate((rng.normal(size=3), rng.uniform(-1, 1, robot.n_joints)))
        dphi = rng.normal(size=robot.n_joints)
        qs = quasi_static(robot, q, dphi)
        assert float(qs.torque @ dphi) == pytest.approx(power(robot, q, dphi, qs.xi), rel=1e-9)
        lateral, rolling = robot.wheel_friction_n()
        assert (np.abs(qs.lateral) <= lateral * (1 + 1e-9)).all()
        assert (np.abs(qs.rolling) <= rolling * (1 + 1e-9)).all()


def test_a_whole_path_in_one_call_is_each_state_solved_on_its_own():
    rng = np.random.default_rng(5)
    for robot in (SNAKE3, SNAKE5, TRIDENT):
        q = np.column_stack((rng.normal(size=(7, 3)), rng.uniform(-1, 1, (7, robot.n_joints))))
        dphi = rng.normal(size=(7, robot.n_joints))
        path = quasi_static_path(robot, q, dphi)
        for k in range(7):
            np.testing.assert_array_equal(path.torque[k], quasi_static(robot, q[k], dphi[k]).torque)
            pos, direction = wheels(robot, q[k])
            np.testing.assert_array_equal(path.pos[k], pos)
            np.testing.assert_array_equal(path.dir[k], direction)


def test_frames_whose_wheels_can_stick_in_several_ways_solve_to_the_least_dissipation():
    """A table of ticks holds joints still for a frame while others turn together
    (snake5's 24.8 deg serpenoid: joints 1 and 4 at rest, 2 and 3 at about one speed):
    several sets of sticking wheels then dissipate the same, a degenerate vertex where
    the solver's pivots come round in a cycle. It must still end at the minimum, in a
    path as on its own."""
    wave = SerpenoidWave(math.radians(24.8), 2 * math.pi, math.radians(60), cycles=3)
    frames = serpenoid_frames(SNAKE5, wave)
    dt = frames.period_ms / 1000.0
    table = Table(frames.angles, dt, frames.loop)
    q = integrate_joints(
        SNAKE5, table, frames.duration_s, samples=frames.steps + 1, options=Options("rk4", h=dt)
    ).q
    mid, dphi = 0.5 * (q[1:] + q[:-1]), np.diff(q[:, 3:], axis=0) / dt
    still = (dphi[:, 0] == 0.0) & (dphi[:, 3] == 0.0)
    assert still.sum() >= 2
    path = quasi_static_path(SNAKE5, mid[still], dphi[still])
    for k, (state, rates) in enumerate(zip(mid[still], dphi[still], strict=True)):
        qs = quasi_static(SNAKE5, state, rates)
        np.testing.assert_array_equal(path.torque[k], qs.torque)
        assert power(SNAKE5, state, rates, qs.xi) == pytest.approx(
            lp_minimum(SNAKE5, state, rates), rel=1e-9, abs=1e-12
        )
        assert float(qs.torque @ rates) == pytest.approx(power(SNAKE5, state, rates, qs.xi))


def test_a_path_names_the_state_it_could_not_solve():
    free = replace(SNAKE3, friction=replace(SNAKE3.friction, rolling=0.0, axle_nm=0.0))
    q = np.array([[0, 0, 0, 0.4, -0.2], [0, 0, 0, 0.4, 0.4]])
    with pytest.raises(SingularConfiguration, match=r"q = \[0\. +0\. +0\. +0\.4 +0\.4\]"):
        quasi_static_path(free, q, np.array([[0.3, 0.1], [0.3, 0.1]]))


def test_only_the_friction_ratios_matter_and_free_rolling_wheels_can_be_singular():
    q = np.array([0, 0, 0, 0.4, 0.4])
    grippy = replace(
        SNAKE3.friction, lateral=8.0, rolling=0.1, axle_nm=SNAKE3.friction.axle_nm * 10
    )
    a = body_velocity(SNAKE3, q, np.array([0.3, 0.1])).xi
    b = body_velocity(SNAKE3, q, np.array([0.3, 0.1]), friction=grippy).xi
    np.testing.assert_allclose(a, b, atol=1e-12)
    free = replace(SNAKE3.friction, rolling=0.0, axle_nm=0.0)
    with pytest.raises(Exception, match="singular"):
        body_velocity(SNAKE3, q, np.array([0.3, 0.1]), friction=free)
