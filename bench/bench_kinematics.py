"""Benchmark: whole trajectories through the C kinematic core against the best Python
we could write with scipy.integrate.solve_ivp on the same models, at matched accuracy.

The Python side gets every advantage we know of: two right-hand sides (numpy arrays, and
plain ``math`` on Python floats, which is faster for these small systems), and each of
scipy's explicit methods (RK45, DOP853) and LSODA. For snake5 the right-hand side is the
quasi-static Coulomb model's exact L1 minimum (qs_reference.py: every vertex at once in
numpy; in ``math`` the last vertices and their neighbours tested for optimality first),
checked against the core's and a HiGHS linear programme's. Accuracy is matched finely:
each Python combination's error against a tight reference (computed by the core) is
taken over a grid of :data:`PER_DECADE` tolerances a decade, and its CPU time at exactly
the core's error is interpolated (log-log) between the two grid points whose errors
bracket it, so no Python side is made several times more accurate than the core (a grid
of whole decades did that: scipy 5-8x more accurate, the ratio flattered by as much).
The fastest combination is the reference; the C core runs Dormand-Prince 8(5,3) at rtol
1e-8, ending its steps at the wheels' switches between sticking and slipping (scipy steps
across them). Where no Python run on the grid is as accurate as the core, each is timed at
the closest error any reaches, and the ratio is printed as the lower bound it is. Every
time is CPU time, each side's fastest of :data:`ROUNDS` interleaved windows of about the
same length (:func:`fastest`: load from elsewhere only ever adds time).
Prints the speed ratio per robot (goal: at least 100x), the ratio curve over the
core's tolerances :data:`CURVE_RTOLS` (the same matching at each), and the batch
throughput of the core over a grid of serpenoid gaits (what a gait search does):
trajectories per second per core, against the same best Python side.

Beside the goal, the core against compiled references at its error (rtol :data:`RTOL`),
matched the same way, the ratio reported with no goal (compiled_reference.py): the same
right-hand sides compiled by numba, under scipy's three methods (what compiling only the
model buys: scipy's stepping stays in Python), and scipy's RK45 and DOP853 compiled end to
end with them (no Python in the loop: an evaluation costs within a few times the core's;
on snake5 the core's lead there is its own stepping, DOP853 ending its steps at the
wheels' switches, with a tenth of the evaluations). The
numba right-hand sides join the model check, the compiled DOP853 is checked to take
scipy's steps, and compiling is timed apart (excluded from the per-trajectory figures).

    .venv/bin/python bench/bench_kinematics.py [--quick]
"""

from __future__ import annotations

import functools
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from compiled_reference import (
    PAIRS,
    Solve,
    compile_seconds,
    compiled_solver,
    for_scipy,
    snake_rhs,
    trident_rhs,
)
from qs_reference import Snake, schedule
from scipy.integrate import solve_ivp

from snakebot.model.kinematics import (
    Inputs,
    Options,
    Sines,
    body_velocity,
    field_velocity,
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
ROUNDS = 7
"""Interleaved rounds of timed windows; each side's figure is its fastest window."""
PER_DECADE = 8
SCIPY_RTOLS = tuple(10.0 ** -(5 + k / PER_DECADE) for k in range(7 * PER_DECADE + 1))
"""rtol 1e-5 to 1e-12, loosest first; atol = rtol / 100."""
CURVE_RTOLS = (1e-7, 1e-8, 1e-9)
PRUNE = 3.0
"""A combination whose one untimed run at the target costs this many times the cheapest's
is not timed in rounds (it cannot be the fastest; the 5-link numpy side would take minutes)."""

Rhs = Callable[[float, np.ndarray], object]
Combos = dict[tuple[str, str], Solve]
"""Each (right-hand side, method) combination's solver."""


def window(fn: Callable[[], object], calls: int) -> float:
    """CPU seconds per call of ``calls`` calls back to back (CPU time, not wall time, so
    that other processes on a shared machine slow neither side by making it wait for a
    core)."""
    start = time.process_time()
    for _ in range(calls):
        fn()
    return (time.process_time() - start) / calls


def calls_for(fn: Callable[[], object], seconds: float) -> int:
    """How many calls of ``fn`` take about ``seconds`` of CPU (at least one)."""
    once = min(window(fn, 1) for _ in range(3))
    return max(1, round(seconds / once)) if once > 0 else 1


def fastest(sides: dict[object, tuple[Callable[[], object], int]]) -> dict[object, float]:
    """Each side's CPU seconds per call: its fastest of :data:`ROUNDS` windows of
    (function, calls), the sides' windows interleaved round by round.

    On this shared virtual machine the CPU time of the same call swings by up to 1.8x for
    a while, from outside the guest (no steal time, no clock change it can see; a busy
    loop on its other CPU changed nothing): the snake5 trajectory took 3.7 to 4.0 ms for
    half a second, then 2.1 ms. A median of a few short windows followed those swings: the
    core's snake5 time varied 1.5x within one run. Other load only ever adds time to a
    fixed computation, so a side's fastest window is what it costs. For fairness every
    side has the same number of windows, interleaved, and the caller makes them about the
    same length (the short calls repeated to last as long as the long ones), so that none
    has more or shorter chances of a quiet moment."""
    best = {key: math.inf for key in sides}
    for _ in range(ROUNDS):
        for key, (fn, calls) in sides.items():
            best[key] = min(best[key], window(fn, calls))
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


def trident_core_rhs(t, q):
    """The C core's velocity at (t, q) under the same inputs, one call at a time: for the
    model check."""
    return field_velocity(TRIDENT, q, np.array(trident_inputs(t)))


# ---- 5-link snake, serpenoid joints, minimum-slip body ----

SNAKE5 = load_robot("snake5")
GAIT = Sines.serpenoid(4, 0.5, 2 * math.pi * 0.5, math.pi / 2)


def snake5_run(rtol=RTOL, atol=ATOL, gait=GAIT):
    return integrate_joints(SNAKE5, gait, SPAN, options=Options(METHOD, rtol, atol))


def snake5_c(rtol=RTOL, atol=ATOL, gait=GAIT):
    return snake5_run(rtol, atol, gait).q[-1, :3]


SNAKE5_PY = Snake(SNAKE5, GAIT)  # the Python counterpart of the quasi-static model


def snake5_core_rhs(t, pose):
    """The C core's body velocity at (t, pose), one call at a time: for the model check."""
    phi, dphi = schedule(GAIT, t)
    return body_velocity(SNAKE5, np.concatenate((pose, phi)), np.array(dphi)).xi


# ---- the comparison ----


def scipy_solver(rhs: Rhs, y0: np.ndarray, method: str) -> Solve:
    """solve_ivp with ``method`` on ``rhs`` from ``y0`` over :data:`SPAN`."""

    def solve(rtol: float) -> tuple[np.ndarray, int]:
        sol = solve_ivp(rhs, (0, SPAN), y0, method=method, rtol=rtol, atol=rtol / 100)
        return sol.y[:, -1], sol.nfev

    return solve


def scipy_combos(rhss: dict[str, Rhs], y0: np.ndarray) -> Combos:
    """Each right-hand side under each of scipy's :data:`METHODS`."""
    return {
        (name, method): scipy_solver(rhs, y0, method)
        for name, rhs in rhss.items()
        for method in METHODS
    }


def errors(
    solve: Solve,
    width: int,
    reference: np.ndarray,
    floor: float,
    grid: tuple[float, ...] = SCIPY_RTOLS,
    budget: float = math.inf,
) -> list[tuple[float, float, int, float]]:
    """(rtol, error, evaluations, CPU seconds of that one run) over ``grid``, loosest
    first, until the error is ten times under ``floor`` (tighter ones cost more and
    bracket nothing) or a run takes more than ``budget`` seconds."""
    points = []
    for rtol in grid:
        start = time.process_time()
        end, nfev = solve(rtol)
        seconds = time.process_time() - start
        err = float(np.abs(end[:width] - reference).max())
        points.append((rtol, err, nfev, seconds))
        if seconds > budget:
            break
        if err < floor / 10:
            break
    return points


def all_curves(
    combos: Combos,
    width: int,
    reference: np.ndarray,
    floor: float,
    grid: tuple[float, ...],
) -> dict[tuple[str, str], list[tuple[float, float, int, float]]]:
    """Every combination's :func:`errors`; once one has reached ``floor``, a later curve
    stops at a run costing :data:`PRUNE` times that one's first run at or under it (it
    cannot be the fastest at any target)."""
    curves = {}
    budget = math.inf
    for key, solve in combos.items():
        points = errors(solve, width, reference, floor, grid, budget)
        curves[key] = points
        reached = [seconds for _, err, _, seconds in points if err <= floor]
        if reached:
            budget = min(budget, PRUNE * reached[0])
    return curves


def bracket(points, target: float) -> tuple[float, float, float, int, float] | None:  # noqa: ANN001
    """(rtol_a, rtol_b, share, evaluations, rough seconds): ``target`` lies ``share`` of
    the way (in log error) from the last grid point above it (a) to the first at or
    under it (b), and the untimed runs' seconds interpolated to it; None if no point
    reaches it."""
    for k, (rtol, err, nfev, seconds) in enumerate(points):
        if err <= target:
            if k == 0 or err == target:
                return rtol, rtol, 0.0, nfev, seconds
            rtol_a, err_a, _, seconds_a = points[k - 1]
            share = math.log(target / err_a) / math.log(err / err_a)
            return rtol_a, rtol, share, nfev, seconds_a * (seconds / seconds_a) ** share
    return None


def matched(
    c_run: Callable[[], object],
    combos: Combos,
    curves: dict[tuple[str, str], list],
    target: float,
) -> tuple[float, float, str, int]:
    """(C seconds, best other seconds, its description, its evaluations) at error
    ``target``: every other combination's two bracketing runs, one call a window, and the
    C run, repeated to last about as long as the fastest of them, timed in interleaved
    rounds (:func:`fastest`), each combination's time interpolated (log-log) to the
    target, the fastest taken (of those within :data:`PRUNE` of the fastest untimed run).
    Where no run on the grid reaches the target, each combination's most accurate run
    stands in for it: a lower bound of what reaching it would cost."""
    runs: dict[tuple[str, str, float], Callable[[], object]] = {}
    found_all = {key: bracket(points, target) for key, points in curves.items()}
    short = all(found is None for found in found_all.values())
    closest: dict[tuple[str, str], float] = {}
    if short:  # no Python run is as accurate as the core: each one's most accurate run
        for key, points in curves.items():
            rtol, err, nfev, seconds = min(points, key=lambda point: point[1])
            found_all[key], closest[key] = (rtol, rtol, 0.0, nfev, seconds), err
    rough = min((found[4] for found in found_all.values() if found), default=math.inf)
    plans = {}
    for (rhs_name, method), found in found_all.items():
        if found is None or found[4] > PRUNE * rough:
            continue
        plans[rhs_name, method] = found[:4]
        for rtol in found[:2]:
            runs[rhs_name, method, rtol] = functools.partial(combos[rhs_name, method], rtol)
    sides: dict[object, tuple[Callable[[], object], int]] = {"C": (c_run, calls_for(c_run, rough))}
    sides.update({key: (run, 1) for key, run in runs.items()})
    times = fastest(sides)
    best = (math.inf, "none reached the C core's accuracy", 0)
    for (rhs_name, method), (rtol_a, rtol_b, share, nfev) in plans.items():
        t_a, t_b = times[rhs_name, method, rtol_a], times[rhs_name, method, rtol_b]
        seconds = t_a * (t_b / t_a) ** share
        if seconds < best[0]:
            rtol = rtol_a * (rtol_b / rtol_a) ** share
            how = f"{method} + {rhs_name} at rtol {rtol:.1e} (interpolated)"
            if short:
                err = closest[rhs_name, method]
                how = (
                    f"{method} + {rhs_name} at rtol {rtol:.1e}, its most accurate: error "
                    f"{err:.1e}, {err / target:.1f}x the core's, so the ratio is a lower bound"
                )
            best = (seconds, how, nfev)
    return times["C"], *best


def check_same_model(rhss: dict[str, Rhs], y0: np.ndarray, others: dict[str, Rhs]) -> str:
    """The Python right-hand sides, and ``others`` (the core's, an LP's), agree at random
    states; returns the check's description."""
    rng = np.random.default_rng(1)
    every = {**rhss, **others}
    worst = 0.0
    for _ in range(5):
        t, y = float(rng.uniform(0, SPAN)), y0 + rng.normal(0, 0.3, len(y0))
        values = [np.asarray(f(t, y), dtype=float) for f in every.values()]
        for v in values[1:]:
            if not np.allclose(values[0], v, rtol=1e-9, atol=1e-12):
                raise SystemExit(f"the right-hand sides disagree at t={t}: {values}")
            worst = max(worst, float(np.abs(v - values[0]).max()))
    return f"{', '.join(every)} agree within {worst:.0e} at 5 random states"


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
            " ns per evaluation of the same method (its sines, cosines and the "
            "friction solve)"
        )
    )


def batch_throughput(amplitudes: int, lags: int) -> tuple[int, float, float]:
    """(trajectories, CPU seconds of the grid, of one trajectory) for 10 s snake5
    serpenoid runs over a grid, the whole grid in one call into the core
    (integrate_joints_batch), and the benchmark's one trajectory a call, repeated to last
    as long: each its fastest window of interleaved rounds (:func:`fastest`)."""
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

    once = window(grid, 1)
    times = fastest({"grid": (grid, 1), "one": (snake5_c, calls_for(snake5_c, once))})
    return len(gaits), times["grid"], times["one"]


@dataclass
class Compiled:
    """The compiled references on one robot's right-hand side: numba's ``rhs`` under
    scipy's :data:`METHODS`, scipy's explicit pairs compiled end to end with it, and the
    CPU seconds compiling them took (their first runs, less a second run: excluded from
    the per-trajectory figures)."""

    rhs: Callable[..., None]
    under_scipy: Combos
    end_to_end: Combos
    compile_s: float

    @classmethod
    def of(cls, rhs: Callable[..., None], y0: np.ndarray) -> Compiled:
        under_scipy = scipy_combos({"numba": for_scipy(rhs, len(y0))}, y0)
        end_to_end = {
            ("numba, all compiled", method): compiled_solver(rhs, y0, SPAN, method)
            for method in PAIRS
        }
        first = [functools.partial(for_scipy(rhs, len(y0)), 0.0, y0)]
        first += [functools.partial(solve, 1e-3) for solve in end_to_end.values()]
        return cls(rhs, under_scipy, end_to_end, compile_seconds(*first))

    def same_steps(self, strict: bool) -> str:
        """scipy's DOP853 and its compiled copy at :data:`RTOL`: the same evaluations and
        the same end (``strict``: to rounding, where the field is smooth; where wheels
        switch between sticking and slipping the steps depend on rounding, and the two
        part by about the run's own error)."""
        (end_s, n_s) = self.under_scipy["numba", "DOP853"](RTOL)
        (end_c, n_c) = self.end_to_end["numba, all compiled", "DOP853"](RTOL)
        gap = float(np.abs(end_s - end_c).max())
        if strict and (n_s != n_c or gap > 1e-9):
            raise SystemExit(
                f"the compiled DOP853 parts from scipy's: {n_c} evaluations to {n_s}, "
                f"ends {gap:.0e} apart"
            )
        return f"compiled DOP853 {n_c} evaluations (scipy's {n_s}), ends {gap:.0e} from scipy's"

    def line(
        self,
        c_func: Callable[..., np.ndarray],
        width: int,
        reference: np.ndarray,
        target: float,
        grid: tuple[float, ...],
    ) -> str:
        """The core against each reference at its error ``target`` (rtol :data:`RTOL`),
        matched as the Python side is."""
        parts = []
        for title, combos in (("numba RHS", self.under_scipy), ("all compiled", self.end_to_end)):
            curves = all_curves(combos, width, reference, target, grid)
            c_at = functools.partial(c_func, RTOL, RTOL / 100)
            t_c, t_ref, how, evals = matched(c_at, combos, curves, target)
            parts.append(
                f"{title} {t_ref * 1e3:.2f} ms ({how}, {evals} evaluations) to the core's "
                f"{t_c * 1e3:.3f} ms in the same rounds: {t_ref / t_c:.1f}x"
            )
        return "; ".join(parts)


def main() -> int:
    quick = "--quick" in sys.argv
    grid = SCIPY_RTOLS[:: PER_DECADE // 4] if quick else SCIPY_RTOLS  # quick: quarter decades
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(
        f"10 s trajectories; C core: {METHOD} at rtol {RTOL:g}, atol {ATOL:g}; "
        f"Python: scipy {', '.join(METHODS)} on a numpy and a plain-math right-hand side, "
        f"each timed at the core's error, interpolated on a grid of {PER_DECADE} tolerances a "
        "decade"
    )
    ratios, python_s = {}, {}
    for name, c_func, c_run, rhss, others, compiled_rhs, y0, width in (
        (
            "trident periodic inputs (h1 loop)",
            trident_c,
            trident_run,
            {"numpy": trident_numpy, "math": trident_math},
            {"C core": trident_core_rhs},
            functools.partial(trident_rhs, trident_inputs, TRIDENT.alphas, TRIDENT.r, TRIDENT.l),
            np.zeros(6),
            6,
        ),
        (
            "snake5 serpenoid joints (quasi-static Coulomb wheels)",
            snake5_c,
            snake5_run,
            {"math": SNAKE5_PY.rhs_math_factory(), "numpy": SNAKE5_PY.rhs_numpy},
            {"C core": snake5_core_rhs, "HiGHS LP": SNAKE5_PY.lp_body_velocity},
            functools.partial(snake_rhs, SNAKE5_PY),
            SNAKE5_PY.y0,
            3,
        ),
    ):
        compiled = Compiled.of(compiled_rhs(), y0)
        numba_rhs = for_scipy(compiled.rhs, len(y0))
        same = check_same_model(rhss, y0, {**others, "numba": numba_rhs})
        reference = c_func(1e-13, 1e-14)
        rtols = (RTOL,) if quick else tuple(sorted({RTOL, *CURVE_RTOLS}, reverse=True))
        curve_c = {
            rtol: float(np.abs(c_func(rtol, rtol / 100) - reference).max()) for rtol in rtols
        }
        python = scipy_combos(rhss, y0)
        curves = all_curves(python, width, reference, min(curve_c.values()), grid)
        closest = min(err for points in curves.values() for _, err, _, _ in points)
        line = []
        for rtol, err_cr in curve_c.items():
            c_at = functools.partial(c_func, rtol, rtol / 100)
            t_cr, t_pr, how_r, evals_r = matched(c_at, python, curves, err_cr)
            bound = " or more (no Python run as accurate)" if "lower bound" in how_r else ""
            line.append(f"rtol {rtol:.0e} (error {err_cr:.1e}): {t_pr / t_cr:.0f}x{bound}")
            if rtol == RTOL:
                t_c, err_c, t_py, how, evals_py = t_cr, err_cr, t_pr, how_r, evals_r
        ratio = t_py / t_c
        where = "" if "lower bound" in how else ", at the core's error"
        ratios[name] = ratio
        python_s[name] = t_py
        print(
            f"{name}:\n  C core {t_c * 1e3:8.3f} ms (error {err_c:.1e})   best Python "
            f"{t_py * 1e3:8.1f} ms ({how}{where})   speed ratio {ratio:6.0f}x "
            f"(goal {GOAL:.0f}x: {'met' if ratio >= GOAL else f'MISS by {GOAL / ratio:.2f}x'})"
        )
        explain_ratio(t_c, int(c_run().stats["evals"]), t_py, evals_py, ratio)
        print("  ratio curve at matched accuracy: " + "; ".join(line))
        print(
            f"  vs compiled references (numba; compiling took {compiled.compile_s:.1f} s CPU, "
            "excluded), C core at its error: "
            + compiled.line(c_func, width, reference, err_c, grid)
        )
        print(f"  same stepping: {compiled.same_steps(strict=name.startswith('trident'))}")
        print(
            f"  same model: {same}; the closest Python trajectory ends {closest:.0e} from "
            "the core's at rtol 1e-13"
        )
    n, cpu, one = batch_throughput(*((4, 4) if quick else (8, 8)))
    snake5_py = next(seconds for name, seconds in python_s.items() if name.startswith("snake5"))
    per_core = n / cpu
    print(
        f"batch: {n} snake5 serpenoid gaits (amplitude x phase lag grid), 10 s each, in one "
        f"call: {per_core:.0f} trajectories per second per core (CPU time); the core one "
        f"trajectory a call: {1 / one:.0f} a second ({one * per_core:.2f}x); the best Python "
        f"at the core's error: {1 / snake5_py:.1f} a second ({per_core * snake5_py:.0f}x)"
    )
    worst = min(ratios.values())
    print(
        f"slowest single-trajectory ratio {worst:.0f}x: "
        f"{'meets' if worst >= GOAL else 'MISSES'} the goal of {GOAL:.0f}x"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
