"""Benchmark: whole trajectories through the C kinematic core against
scipy.integrate.solve_ivp on a numpy implementation of the same models.

Both sides use the same method (Dormand-Prince 5(4): scipy's RK45, the core's DOPRI5)
and the same tolerances, so they take comparable steps; both are checked against a
tight reference to show they reach the same accuracy. Prints the speed ratio per case
(goal: the C core at least 100x faster).
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy.integrate import solve_ivp

from snakebot.kinematics import Inputs, Options, Sines, integrate_fields, integrate_joints
from snakebot.robots import load_robot

RTOL, ATOL = 1e-8, 1e-10
GOAL = 100.0
SPAN = 10.0


def best_times(fast, slow, rounds=5, fast_repeats=10):
    """Best wall time of each, measured in alternation so that load from other processes
    on a shared machine hits both sides alike."""
    best_fast = best_slow = math.inf
    result_fast = result_slow = None
    for _ in range(rounds):
        for _ in range(fast_repeats):
            start = time.perf_counter()
            result_fast = fast()
            best_fast = min(best_fast, time.perf_counter() - start)
        start = time.perf_counter()
        result_slow = slow()
        best_slow = min(best_slow, time.perf_counter() - start)
    return best_fast, result_fast, best_slow, result_slow


# ---- trident, body-velocity inputs, a loop in (u1, u2): motion along h1 = [g1, g2] ----

TRIDENT = load_robot("trident")
AMP, OMEGA = 0.3, 2 * math.pi
ALPHAS = np.array(TRIDENT.alphas)


def trident_rhs(t, q, alphas=ALPHAS, r=TRIDENT.r, arm=TRIDENT.l):
    u1, u2, u3 = -AMP * OMEGA * math.sin(OMEGA * t), AMP * OMEGA * math.cos(OMEGA * t), 0.0
    c, s = math.cos(q[2]), math.sin(q[2])
    phi = q[3:]
    nu = alphas + phi
    dphi = (np.sin(nu) * u1 - np.cos(nu) * u2 - (r * np.cos(phi) + arm) * u3) / arm
    return np.concatenate(([c * u1 - s * u2, s * u1 + c * u2, u3], dphi))


def trident_c(rtol=RTOL, atol=ATOL):
    inputs = Inputs((0.0, 0.0, 0.0), (-AMP * OMEGA, 0.0, 0.0), (0.0, AMP * OMEGA, 0.0), OMEGA)
    return integrate_fields(TRIDENT, inputs, SPAN, options=Options("dopri5", rtol, atol)).q[-1]


def trident_scipy():
    sol = solve_ivp(trident_rhs, (0, SPAN), np.zeros(6), method="RK45", rtol=RTOL, atol=ATOL)
    return sol.y[:, -1]


# ---- 5-link snake, serpenoid joints, minimum-slip body ----

SNAKE5 = load_robot("snake5")
GAIT = Sines.serpenoid(4, 0.5, 2 * math.pi * 0.5, math.pi / 2)


def snake5_rhs(t, pose, robot=SNAKE5, gait=GAIT):
    phase = gait.omega * t + np.array(gait.phase)
    phi = np.array(gait.amp) * np.sin(phase)
    dphi = np.array(gait.amp) * gait.omega * np.cos(phase)
    half = robot.l
    psi = pose[2] + np.concatenate(([0.0], np.cumsum(phi)))  # link headings
    tx, ty = np.cos(psi), np.sin(psi)
    # joint k sits at the far end of link k; wheel k at the middle of link k
    starts = pose[:2] + 2 * half * np.vstack(([0.0, 0.0], np.cumsum(np.c_[tx, ty], axis=0)[:-1]))
    wheels = starts + half * np.c_[tx, ty]
    rel = wheels - pose[:2]
    n_theta = tx * rel[:, 0] + ty * rel[:, 1]
    t_theta = -(-ty * rel[:, 0] + tx * rel[:, 1])
    n_joint, t_joint = np.zeros(len(psi)), np.zeros(len(psi))
    for k in range(1, len(psi)):
        d = wheels[k] - starts[1 : k + 1]  # offsets from the joints before link k
        n_joint[k] = dphi[:k] @ (tx[k] * d[:, 0] + ty[k] * d[:, 1])
        t_joint[k] = -dphi[:k] @ (-ty[k] * d[:, 0] + tx[k] * d[:, 1])
    wn, wt = math.sqrt(robot.c_n), math.sqrt(robot.c_t)
    m = np.vstack((np.c_[-ty, tx, n_theta] * wn, np.c_[tx, ty, t_theta] * wt))
    b = -np.concatenate((n_joint * wn, t_joint * wt))
    return np.linalg.lstsq(m, b, rcond=None)[0]


def snake5_c(rtol=RTOL, atol=ATOL):
    return integrate_joints(SNAKE5, GAIT, SPAN, options=Options("dopri5", rtol, atol)).q[-1, :3]


def snake5_scipy():
    sol = solve_ivp(snake5_rhs, (0, SPAN), np.zeros(3), method="RK45", rtol=RTOL, atol=ATOL)
    return sol.y[:, -1]


def main() -> int:
    print(f"10 s trajectories, Dormand-Prince 5(4) at rtol {RTOL:g}, atol {ATOL:g} on both sides")
    ratios = []
    for name, c_func, py_func in (
        ("trident periodic inputs (h1 loop)", trident_c, trident_scipy),
        ("5-link serpenoid (minimum slip)", snake5_c, snake5_scipy),
    ):
        reference = c_func(1e-13, 1e-14)
        t_c, final_c, t_py, final_py = best_times(c_func, py_func)
        err_c = float(np.abs(final_c - reference).max())
        err_py = float(np.abs(final_py - reference).max())
        ratio = t_py / t_c
        ratios.append(ratio)
        print(
            f"{name}:\n  C core {t_c * 1e3:8.3f} ms (error {err_c:.1e})   scipy+numpy "
            f"{t_py * 1e3:8.1f} ms (error {err_py:.1e})   speed ratio {ratio:7.0f}x"
        )
        if max(err_c, err_py) > 1e-5:
            print("  accuracy check FAILED: the two sides disagree with the reference")
            return 1
    worst = min(ratios)
    verdict = "meets" if worst >= GOAL else "MISSES"
    print(f"slowest ratio {worst:.0f}x: {verdict} the goal of {GOAL:.0f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
