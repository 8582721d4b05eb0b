"""The core's minimum-slip solve takes the normal equations where the problem is well
conditioned and Householder QR elsewhere: on both sides of that switch its body
velocity must be the weighted least-squares solution that numpy finds from the same
wheel speeds (the core's own wheel geometry, read through kin_wheel_speeds)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from snakebot.model.kinematics.ccore import KinematicsError
from snakebot.model.kinematics.model import body_velocity, wheel_speeds
from snakebot.model.robots import load_robot

SNAKE5 = load_robot("snake5")
SWITCH_RCOND = 1e-2  # where the core changes method (NORMAL_RCOND in kin_geom.c)
IDEAL = replace(SNAKE5, c_t=0.0)  # ideal wheels: singular when straight
BENDS = (1.0, 0.03, 0.003)  # joint angle scales: a nearly straight snake is ill conditioned


def numpy_xi(robot, q: np.ndarray, dphi: np.ndarray, c_t: float) -> np.ndarray:
    """argmin over xi of sum c_n (n.v)^2 + c_t (t.v)^2, the wheel speeds v being affine
    in xi: their map and offset read off kin_wheel_speeds, solved by numpy."""

    def speeds(xi: np.ndarray) -> np.ndarray:
        normal, tangent = wheel_speeds(robot, q, np.concatenate((xi, dphi)))
        return np.concatenate((math.sqrt(robot.c_n) * normal, math.sqrt(c_t) * tangent))

    offset = speeds(np.zeros(3))
    columns = np.column_stack([speeds(e) - offset for e in np.eye(3)])
    return np.linalg.lstsq(columns, -offset, rcond=None)[0]


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-2.5, 2.5), min_size=4, max_size=4),
    st.lists(st.floats(-2.0, 2.0), min_size=4, max_size=4),
    st.sampled_from([0.0, 0.05, 1.0]),
    st.sampled_from(BENDS),
)
def test_body_velocity_is_numpys_least_squares_on_either_side_of_the_switch(phi, dphi, c_t, bend):
    robot = replace(SNAKE5, c_t=c_t)
    q = np.array([0.3, -0.2, 0.7, *(bend * np.array(phi))])
    try:
        bv = body_velocity(robot, q, np.array(dphi))
    except KinematicsError:
        return  # singular: nothing to compare
    expected = numpy_xi(robot, q, np.array(dphi), c_t)
    if bv.rcond == 0.0:  # exactly singular (a straight ideal-wheeled snake) at rest
        np.testing.assert_array_equal(bv.xi, expected)
        return
    # QR and the normal equations alike: within eps / rcond^2 of the exact solution
    scale = max(1.0, np.abs(expected).max())
    tol = 1e-13 / min(bv.rcond, SWITCH_RCOND) ** 2
    np.testing.assert_allclose(bv.xi, expected, rtol=0, atol=max(1e-12, tol) * scale)


@pytest.mark.parametrize("below", [True, False])
def test_both_methods_are_exercised(below):
    # Configurations on each side of the switch exist among the poses the property above
    # draws, so it covers both solves.
    rng = np.random.default_rng(7)
    for _ in range(2000):
        q = np.array([0.0, 0.0, 0.0, *rng.choice(BENDS) * rng.uniform(-2.5, 2.5, 4)])
        try:
            rc = body_velocity(IDEAL, q, rng.uniform(-1, 1, 4)).rcond
        except KinematicsError:
            continue
        if (rc < SWITCH_RCOND) == below:
            return
    pytest.fail(
        f"no ideal-wheeled snake5 pose with rcond {'below' if below else 'above'} {SWITCH_RCOND}"
    )
