"""Benchmark: whole trajectories through the C kinematic core against the best Python
we could write with scipy.integrate.solve_ivp on the same models.

The Python side gets every advantage we know of: two right-hand sides (numpy arrays,
and plain ``math`` on Python floats, which is faster for these small systems), and
each of scipy's explicit methods (RK45, DOP853) and LSODA, each at the loosest
tolerance that is at least as accurate as the C core, against a tight reference
computed by the core. The fastest of those is the reference; the C core runs
Dormand-Prince 8(5,3) at rtol 1e-8. Prints the speed ratio per robot (goal: at least
100x) and the batch throughput of the core over a grid of serpenoid gaits (what a gait
search does): trajectories per second per core, against the same best Python side.

    .venv/bin/python bench/bench_kinematics.py [--quick]
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Callable

import numpy as np
from scipy.integrate import solve_ivp

from snakebot.model.kinematics import (
    Inputs,
    Options,
    Sines,
    integrate_fields,
    integrate_joints,
    integrate_joints_batch,
)
from snakebot.model.robots import load_robot

RTOL, ATOL = 1e-8, 1e-10
METHOD = "dop853"  # the core's method; "dopri5" for Dormand-Prince 5(4)
GOAL = 100.0
SPAN = 10.0
METHODS = ("RK45", "DOP853", "LSODA")
C_ROUNDS, PY_ROUNDS = 20, 5  # each side's best: the core's runs are short, so more of them
SCIPY_RTOLS = tuple(10.0**-e for e in range(5, 13))  # loosest first; atol = rtol / 100

Rhs = Callable[[float, np.ndarray], object]


def best_time(fn: Callable[[], object], rounds: int) -> float:
    """The least CPU time of ``rounds`` calls: CPU time, not wall time, so that other
    processes on a shared machine slow neither side by making it wait for a core."""
    best = math.inf
    for _ in range(rounds):
        start = time.process_time()
        fn()
        best = min(best, time.process_time() - start)
    return best


# ---- trident, body-velocity inputs, a loop in (u1, u2): motion along h1 = [g1, g2] ----

TRIDENT = load_robot("trident")
AMP, OMEGA = 0.3, 2 * math.pi
ALPHAS = np.array(TRIDENT.alphas)


def trident_inputs(t: float) -> tuple[float, float, float]:
    return -AMP * OMEGA * math.sin(OMEGA * t), AMP * OMEGA * math.cos(OMEGA * t), 0.0


def trident_numpy(t, q, alphas=ALPHAS, r=TRIDENT.r, arm=TRIDENT.l):
    u1, u2, u3 = trident_inputs(t)
    c, s = math.cos(q[2]), math.sin(q[2])
    phi = q[3:]
    nu = alphas + phi
    dphi = (np.sin(nu) * u1 - np.cos(nu) * u2 - (r * np.cos(phi) + arm) * u3) / arm
    return np.concatenate(([c * u1 - s * u2, s * u1 + c * u2, u3], dphi))


def trident_math(t, q, alphas=tuple(TRIDENT.alphas), r=TRIDENT.r, arm=TRIDENT.l):
    u1, u2, u3 = trident_inputs(t)
    _, _, theta, *phi = q.tolist()
    c, s = math.cos(theta), math.sin(theta)
    out = [c * u1 - s * u2, s * u1 + c * u2, u3]
    for a, p in zip(alphas, phi, strict=True):
        out.append(
            (math.sin(a + p) * u1 - math.cos(a + p) * u2 - (r * math.cos(p) + arm) * u3) / arm
        )
    return out


def trident_run(rtol=RTOL, atol=ATOL):
    inputs = Inputs((0.0, 0.0, 0.0), (-AMP * OMEGA, 0.0, 0.0), (0.0, AMP * OMEGA, 0.0), OMEGA)
    return integrate_fields(TRIDENT, inputs, SPAN, options=Options(METHOD, rtol, atol))


def trident_c(rtol=RTOL, atol=ATOL):
    return trident_run(rtol, atol).q[-1]


# ---- 5-link snake, serpenoid joints, minimum-slip body ----

SNAKE5 = load_robot("snake5")
GAIT = Sines.serpenoid(4, 0.5, 2 * math.pi * 0.5, math.pi / 2)


def snake5_run(rtol=RTOL, atol=ATOL, gait=GAIT):
    return integrate_joints(SNAKE5, gait, SPAN, options=Options(METHOD, rtol, atol))


def snake5_c(rtol=RTOL, atol=ATOL, gait=GAIT):
    return snake5_run(rtol, atol, gait).q[-1, :3]


# ---- the comparison ----


def scipy_run(rhs: Rhs, y0: np.ndarray, method: str, rtol: float, width: int) -> np.ndarray:
    return scipy_solve(rhs, y0, method, rtol).y[:width, -1]


def scipy_solve(rhs: Rhs, y0: np.ndarray, method: str, rtol: float):
    return solve_ivp(rhs, (0, SPAN), y0, method=method, rtol=rtol, atol=rtol / 100)


def best_python(
    rhss: dict[str, Rhs], y0: np.ndarray, width: int, reference: np.ndarray, target: float
) -> tuple[float, str, float, int]:
    """(seconds, description, error, right-hand-side evaluations) of the fastest
    right-hand side and method at the loosest tolerance whose error is at most ``target``."""
    best = (math.inf, "none reached the C core's accuracy", math.nan, 0)
    for rhs_name, rhs in rhss.items():
        for method in METHODS:
            for rtol in SCIPY_RTOLS:
                sol = scipy_solve(rhs, y0, method, rtol)
                err = float(np.abs(sol.y[:width, -1] - reference).max())
                if err <= target:
                    seconds = best_time(
                        lambda f=rhs, m=method, r=rtol: scipy_run(f, y0, m, r, width), PY_ROUNDS
                    )
                    if seconds < best[0]:
                        best = (seconds, f"{method} + {rhs_name} at rtol {rtol:.0e}", err, sol.nfev)
                    break
    return best


def check_same_model(rhss: dict[str, Rhs], y0: np.ndarray) -> None:
    rng = np.random.default_rng(1)
    for _ in range(5):
        t, y = float(rng.uniform(0, SPAN)), y0 + rng.normal(0, 0.3, len(y0))
        values = [np.asarray(f(t, y), dtype=float) for f in rhss.values()]
        if not np.allclose(values[0], values[1], rtol=1e-9, atol=1e-12):
            raise SystemExit(f"the right-hand sides disagree at t={t}: {values}")


def explain_ratio(t_c: float, evals_c: int, t_py: float, evals_py: int, ratio: float) -> None:
    """The ratio as (evaluations the Python side needs per C evaluation) x (cost of one
    Python evaluation, its integrator's bookkeeping included, per C evaluation): a miss
    says which factor is short."""
    per_c, per_py = t_c / evals_c, t_py / evals_py
    print(
        f"  why: C {evals_c} evaluations at {per_c * 1e9:.0f} ns each (call overhead "
        f"included); Python {evals_py} at {per_py * 1e6:.1f} us each: "
        f"{evals_py / evals_c:.2f} x {per_py / per_c:.0f} = {ratio:.0f}x"
        + (
            ""
            if ratio >= GOAL
            else f"; {GOAL:.0f}x needs the C core at {per_py * evals_py / GOAL / evals_c * 1e9:.0f}"
            " ns per evaluation of the same method (its sines, cosines and the least "
            "squares)"
        )
    )


def batch_throughput(amplitudes: int, lags: int) -> tuple[int, float]:
    """(trajectories, CPU seconds) for 10 s snake5 serpenoid runs over a grid, the whole
    grid in one call into the core (integrate_joints_batch); the best of C_ROUNDS."""
    gaits = [
        Sines.serpenoid(4, amp, 2 * math.pi * 0.5, delta)
        for amp in np.linspace(0.2, 0.8, amplitudes)
        for delta in np.linspace(0.3, 2.0, lags)
    ]
    options = Options(METHOD, RTOL, ATOL)

    def grid() -> None:
        batch = integrate_joints_batch(SNAKE5, gaits, SPAN, options=options)
        if batch.status.any():
            raise SystemExit(f"a grid trajectory failed: {batch.error(int(batch.status.argmax()))}")

    return len(gaits), best_time(grid, max(1, C_ROUNDS // 4))


def main() -> int:
    quick = "--quick" in sys.argv
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(
        f"10 s trajectories; C core: {METHOD} at rtol {RTOL:g}, atol {ATOL:g}; "
        f"Python: scipy {', '.join(METHODS)} on a numpy and a plain-math right-hand side, "
        "each at the loosest tolerance as accurate as the core"
    )
    ratios = {}
    for name, c_func, c_run, rhss, y0, width in (
        (
            "trident periodic inputs (h1 loop)",
            trident_c,
            trident_run,
            {"numpy": trident_numpy, "math": trident_math},
            np.zeros(6),
            6,
        ),
    ):
        check_same_model(rhss, y0)
        reference = c_func(1e-13, 1e-14)
        t_c = best_time(c_func, C_ROUNDS)
        err_c = float(np.abs(c_func() - reference).max())
        t_py, how, err_py, evals_py = best_python(rhss, y0, width, reference, err_c)
        ratio = t_py / t_c
        ratios[name] = ratio
        print(
            f"{name}:\n  C core {t_c * 1e3:8.3f} ms (error {err_c:.1e})   best Python "
            f"{t_py * 1e3:8.1f} ms ({how}, error {err_py:.1e})   speed ratio {ratio:6.0f}x "
            f"(goal {GOAL:.0f}x: {'met' if ratio >= GOAL else 'MISS'})"
        )
        explain_ratio(t_c, int(c_run().stats["evals"]), t_py, evals_py, ratio)
    # No 5-link comparison: the core solves the quasi-static L1 problem (issue 31) and no
    # Python counterpart of it is written yet.
    n, cpu = batch_throughput(*((4, 4) if quick else (8, 8)))
    per_core = n / cpu
    print(
        f"batch: {n} snake5 serpenoid gaits (amplitude x phase lag grid), 10 s each: "
        f"{per_core:.0f} trajectories per second per core (CPU time)"
    )
    worst = min(ratios.values())
    print(
        f"slowest single-trajectory ratio {worst:.0f}x: "
        f"{'meets' if worst >= GOAL else 'MISSES'} the goal of {GOAL:.0f}x"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
