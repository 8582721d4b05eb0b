"""The loop solver's batches: a stack of loops integrated in one call into the core gives
each loop's motion as alone, and the batched Jacobian is SciPy's own forward
differences, so batching changes what the planner costs, not what it plans."""

from __future__ import annotations

import numpy as np
from scipy.optimize._numdiff import approx_derivative

from snakebot.model.kinematics import Table, integrate_joints
from snakebot.model.plan.loops import (
    HARMONICS,
    SOLVE_OPTIONS,
    batched,
    loop_angles,
    path_motion,
    path_motions,
)
from snakebot.model.robots import load_robot

SNAKE3 = load_robot("snake3")
HUB = np.array([0.5, -1.4])  # one of the 3-link snake's hubs, near its singular line


def test_a_stack_of_loops_moves_the_body_as_each_loop_alone():
    rng = np.random.default_rng(5)
    coefficients = rng.normal(0.0, 0.3, (6, SNAKE3.n_joints * 2 * HARMONICS))
    stack = loop_angles(HUB, coefficients)
    moved, rcond, integrated = path_motions(SNAKE3, stack)
    assert integrated.all()
    for k, row in enumerate(coefficients):
        angles = loop_angles(HUB, row)
        np.testing.assert_array_equal(stack[k], angles)
        np.testing.assert_array_equal(moved[k], path_motion(SNAKE3, angles))
        alone = integrate_joints(
            SNAKE3, Table(angles, 1.0), len(angles) - 1.0, options=SOLVE_OPTIONS
        )
        assert rcond[k] == alone.stats["min_rcond"]
    assert np.abs(moved).max() > 0.01  # the loops do move it


def test_the_batched_jacobian_is_scipys_forward_differences():
    weights = np.array([[1.0, -2.0, 0.5], [0.3, 0.0, 4.0]])

    def residuals(stack: np.ndarray) -> np.ndarray:
        return np.column_stack((np.sin(stack @ weights.T), np.exp(stack[:, :1])))

    residual, jacobian = batched(residuals)
    for x in (np.array([0.2, -3.0, 1e-9]), np.array([-0.7, 0.0, 250.0])):
        f0 = residual(x)
        np.testing.assert_array_equal(f0, residuals(x[None, :])[0])
        want = approx_derivative(residual, x, method="2-point", f0=f0)
        np.testing.assert_array_equal(jacobian(x), want)
    # at an upper bound the differences step backwards, as SciPy's do
    bounds = (np.array([-1.0, -5.0, 0.0]), np.array([0.2, 5.0, 1e-9]))
    residual, jacobian = batched(residuals, bounds)
    x = np.array([0.2, -3.0, 1e-9])
    want = approx_derivative(residual, x, method="2-point", f0=residual(x), bounds=bounds)
    np.testing.assert_array_equal(jacobian(x), want)
