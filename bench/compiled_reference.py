"""Compiled references for bench_kinematics.py: its right-hand sides compiled by numba,
driven by scipy's solvers, and scipy's explicit Runge-Kutta pairs compiled end to end.

Two references, both at the Python side's matched accuracy:

- the right-hand side compiled (numba ``@njit``) under ``scipy.integrate.solve_ivp``
  (RK45, DOP853, LSODA): what a Python user reaches for first; scipy's own stepping,
  in Python, remains;
- the whole integration compiled: scipy's RK45 and DOP853 (their Butcher tableaux and
  error estimators read from scipy, the step control as scipy's: the same initial step,
  safety factor and bounds on the step change), numba-compiled, calling the compiled
  right-hand side directly: no Python in the loop. At the same rtol it takes scipy's
  steps (the bench checks that it ends where scipy's run ends, with as many evaluations).

The right-hand sides are those of bench_kinematics.py: the trident's field under
body-velocity inputs (the input law is the bench's own function, compiled as it is), and
the snake's quasi-static L1 minimum as qs_reference.py's plain-``math`` side finds it
(the last optimal vertices first, then the last one's neighbours, each accepted when it
passes the optimality test; only if none does, every vertex compared). Each right-hand
side has the signature ``rhs(t, y, out, memory)``: it writes the derivative into
``out``; ``memory`` is an int64 array the snake keeps its last optimal vertices in.

Compilation happens on the first call of each function (no cache on disk, so each run
measures it): :func:`compile_seconds` times it apart from the trajectories.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from numba import njit
from qs_reference import CERTIFY, DEPENDENT, RECENT, Snake
from scipy.integrate._ivp import rk

Solve = Callable[[float], tuple[np.ndarray, int]]
"""rtol -> (the state at the end, right-hand-side evaluations); atol is rtol / 100."""

EPS = float(np.finfo(float).eps)
SAFETY, MIN_FACTOR, MAX_FACTOR = rk.SAFETY, rk.MIN_FACTOR, rk.MAX_FACTOR
"""scipy's step control (rk.py), as plain floats the compiled code freezes."""


def trident_rhs(inputs: Callable[[float], tuple[float, float, float]], alphas, r, arm):
    """The trident's field under body-velocity inputs ``u = inputs(t)``: the bench's
    ``trident_math``, compiled (``inputs`` is compiled too)."""
    law = njit(inputs)
    alphas = np.asarray(alphas, dtype=float)
    r, arm = float(r), float(arm)

    @njit
    def rhs(t, q, out, memory):
        u1, u2, u3 = law(t)
        c, s = math.cos(q[2]), math.sin(q[2])
        out[0] = c * u1 - s * u2
        out[1] = s * u1 + c * u2
        out[2] = u3
        for i in range(alphas.size):
            p = q[3 + i]
            nu = alphas[i] + p
            out[3 + i] = (
                math.sin(nu) * u1 - math.cos(nu) * u2 - (r * math.cos(p) + arm) * u3
            ) / arm

    return rhs


def snake_rhs(snake: Snake):
    """The snake's quasi-static body velocity (qs_reference.py's ``rhs_math_factory``),
    compiled; its memory of the last optimal vertices is ``memory`` (see :func:`memory`)."""
    gait = snake.gait
    m = len(gait.amp)
    omega = float(gait.omega)
    amp = np.asarray(gait.amp, dtype=float)
    phase = np.asarray(gait.phase, dtype=float)
    offset = np.asarray(gait.offset or (0.0,) * m, dtype=float)
    rate = np.asarray(gait.rate or (0.0,) * m, dtype=float)
    links, half = snake.links, float(snake.l)
    weights = np.asarray(snake.weights, dtype=float)
    triples = np.array(snake.triples, dtype=np.int64)
    ids = {triple: k for k, triple in enumerate(snake.triples)}
    adjacent = np.array([[ids[n] for n in snake.adjacent[t]] for t in snake.triples])
    n_rows = 2 * links

    @njit
    def rows_of(t, theta):
        rows = np.empty((n_rows, 4))
        psi, s = theta, 0.0
        gx = gy = hx = hy = 0.0
        for k in range(links):
            if k:
                arg = omega * t + phase[k - 1]
                psi += offset[k - 1] + rate[k - 1] * t + amp[k - 1] * math.sin(arg)
                s += rate[k - 1] + amp[k - 1] * omega * math.cos(arg)
            cs, sn = math.cos(psi), math.sin(psi)
            g_x, g_y = gx - half * sn, gy + half * cs
            h_x, h_y = hx - half * s * sn, hy + half * s * cs
            rows[2 * k, 0], rows[2 * k, 1] = -sn, cs
            rows[2 * k, 2], rows[2 * k, 3] = cs * g_y - sn * g_x, cs * h_y - sn * h_x
            rows[2 * k + 1, 0], rows[2 * k + 1, 1] = cs, sn
            rows[2 * k + 1, 2], rows[2 * k + 1, 3] = cs * g_x + sn * g_y, cs * h_x + sn * h_y
            gx, gy = gx - 2 * half * sn, gy + 2 * half * cs
            hx, hy = hx - 2 * half * s * sn, hy + 2 * half * s * cs
        return rows

    @njit
    def vertex(rows, k, x, inv):
        """Triple ``k``'s vertex into ``x`` and the inverse's columns (times det) into
        ``inv``; its determinant, or 0.0 if the rows are dependent."""
        i, j, l3 = triples[k, 0], triples[k, 1], triples[k, 2]
        a, b, c = rows[i], rows[j], rows[l3]
        inv[0], inv[1], inv[2] = (
            b[1] * c[2] - b[2] * c[1],
            b[2] * c[0] - b[0] * c[2],
            b[0] * c[1] - b[1] * c[0],
        )
        inv[3], inv[4], inv[5] = (
            c[1] * a[2] - c[2] * a[1],
            c[2] * a[0] - c[0] * a[2],
            c[0] * a[1] - c[1] * a[0],
        )
        inv[6], inv[7], inv[8] = (
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        )
        det = a[0] * inv[0] + a[1] * inv[1] + a[2] * inv[2]
        size = math.sqrt(
            (a[0] ** 2 + a[1] ** 2 + a[2] ** 2)
            * (b[0] ** 2 + b[1] ** 2 + b[2] ** 2)
            * (c[0] ** 2 + c[1] ** 2 + c[2] ** 2)
        )
        if not abs(det) > DEPENDENT * size:
            return 0.0
        for d in range(3):
            x[d] = -(a[3] * inv[d] + b[3] * inv[3 + d] + c[3] * inv[6 + d]) / det
        return det

    @njit
    def optimal(rows, k, x, inv, det):
        """Zero is a subgradient at triple ``k``'s vertex ``x`` (qs_reference's test)."""
        big_c = big_a = 0.0
        for row in range(n_rows):
            big_c = max(big_c, abs(rows[row, 3]))
            big_a = max(big_a, abs(rows[row, 0]), abs(rows[row, 1]), abs(rows[row, 2]))
        scale = big_c + max(abs(x[0]), abs(x[1]), abs(x[2])) * big_a
        gx = gy = gz = 0.0
        for row in range(n_rows):
            if row == triples[k, 0] or row == triples[k, 1] or row == triples[k, 2]:
                continue
            speed = rows[row, 0] * x[0] + rows[row, 1] * x[1] + rows[row, 2] * x[2] + rows[row, 3]
            if abs(speed) <= 1e-12 * scale:
                return False
            f = weights[row] if speed > 0.0 else -weights[row]
            gx, gy, gz = gx + f * rows[row, 0], gy + f * rows[row, 1], gz + f * rows[row, 2]
        for j in range(3):
            force = -(inv[3 * j] * gx + inv[3 * j + 1] * gy + inv[3 * j + 2] * gz) / det
            if abs(force) > weights[triples[k, j]] * (1.0 + CERTIFY):
                return False
        return True

    @njit
    def remember(memory, k):
        """Triple ``k`` to the front of the last optimal ones (memory[0] of them held)."""
        held = memory[0]
        at = held
        for i in range(held):
            if memory[1 + i] == k:
                at = i
        if at == held:
            held = min(held + 1, RECENT)
            at = held - 1
        for i in range(at, 0, -1):
            memory[1 + i] = memory[i]
        memory[1] = k
        memory[0] = held

    @njit
    def rhs(t, pose, out, memory):
        rows = rows_of(t, pose[2])
        x = np.empty(3)
        inv = np.empty(9)
        held = memory[0]
        last = memory[1]
        for c in range(held + (adjacent.shape[1] if held else 0)):
            k = memory[1 + c] if c < held else adjacent[last, c - held]
            det = vertex(rows, k, x, inv)
            if det != 0.0 and optimal(rows, k, x, inv, det):
                remember(memory, k)
                out[0], out[1], out[2] = x[0], x[1], x[2]
                return
        best, best_power = -1, math.inf
        for k in range(triples.shape[0]):
            if vertex(rows, k, x, inv) != 0.0:
                power = 0.0
                for row in range(n_rows):
                    speed = rows[row, 0] * x[0] + rows[row, 1] * x[1] + rows[row, 2] * x[2]
                    power += weights[row] * abs(speed + rows[row, 3])
                if power < best_power:
                    best, best_power = k, power
                    out[0], out[1], out[2] = x[0], x[1], x[2]
        if best < 0:
            raise ArithmeticError("the wheels fix no body velocity")
        remember(memory, best)

    return rhs


def memory() -> np.ndarray:
    """A fresh memory for a right-hand side: no optimal vertex known yet."""
    return np.zeros(1 + RECENT, dtype=np.int64)


def for_scipy(rhs, size: int) -> Callable[[float, np.ndarray], np.ndarray]:
    """``rhs`` as solve_ivp calls a right-hand side: f(t, y) returning the derivative."""
    held = memory()

    def f(t: float, y: np.ndarray) -> np.ndarray:
        out = np.empty(size)
        rhs(t, y, out, held)
        return out

    return f


@njit
def _rms(v):
    return math.sqrt(np.sum(v * v) / v.size)


@njit
def _integrate(rhs, memory, y0, t1, rtol, atol, a, b, c, e5, e3, order, dop853):
    """scipy's explicit Runge-Kutta stepping (rk.py's _step_impl, common.py's initial
    step) from t = 0 to ``t1``; (the end state, evaluations), -1 evaluations if the step
    became too small. ``dop853``: DOP853's error norm from its E5 and E3 estimators;
    else ``e5`` is the pair's single estimator."""
    n, stages = y0.size, b.size
    k = np.empty((stages + 1, n))
    y, y_new, f0, f1 = y0.copy(), np.empty(n), np.empty(n), np.empty(n)
    rhs(0.0, y, f0, memory)
    scale = atol + np.abs(y) * rtol
    d0, d1 = _rms(y / scale), _rms(f0 / scale)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, t1)
    rhs(h0, y + h0 * f0, f1, memory)
    d2 = _rms((f1 - f0) / scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1))
    h_abs = min(100 * h0, h1, t1)
    evals = 2
    exponent = -1.0 / (order + 1)
    t = 0.0
    while t < t1:
        min_step = 10 * EPS * abs(t)
        h_abs = max(h_abs, min_step)
        rejected = False
        while True:
            if h_abs < min_step:
                return y, -1
            t_new = min(t + h_abs, t1)
            h = t_new - t
            k[0] = f0  # the derivative at the step's start
            for s in range(1, stages):
                for j in range(n):
                    acc = 0.0
                    for q in range(s):
                        acc += k[q, j] * a[s, q]
                    y_new[j] = y[j] + acc * h
                rhs(t + c[s] * h, y_new, k[s], memory)
            for j in range(n):
                acc = 0.0
                for q in range(stages):
                    acc += k[q, j] * b[q]
                y_new[j] = y[j] + h * acc
            rhs(t + h, y_new, k[stages], memory)
            evals += stages
            n5 = n3 = 0.0  # the squared norms of the scaled error estimates
            for j in range(n):
                sc = atol + max(abs(y[j]), abs(y_new[j])) * rtol
                est5 = est3 = 0.0
                for q in range(stages + 1):
                    est5 += k[q, j] * e5[q]
                    est3 += k[q, j] * e3[q]
                n5 += (est5 / sc) ** 2
                n3 += (est3 / sc) ** 2
            if not dop853:
                norm = abs(h) * math.sqrt(n5 / n)
            elif n5 == 0.0 and n3 == 0.0:
                norm = 0.0
            else:
                norm = abs(h) * n5 / math.sqrt((n5 + 0.01 * n3) * n)
            if norm < 1.0:
                factor = MAX_FACTOR if norm == 0.0 else min(MAX_FACTOR, SAFETY * norm**exponent)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            h_abs *= max(MIN_FACTOR, SAFETY * norm**exponent)
            rejected = True
        t = t_new
        y[:] = y_new
        f0[:] = k[stages]
    return y, evals


PAIRS = {
    "RK45": (
        rk.RK45.A,
        rk.RK45.B,
        rk.RK45.C,
        rk.RK45.E,
        rk.RK45.E,
        rk.RK45.error_estimator_order,
        False,
    ),
    "DOP853": (
        rk.DOP853.A,
        rk.DOP853.B,
        rk.DOP853.C,
        rk.DOP853.E5,
        rk.DOP853.E3,
        rk.DOP853.error_estimator_order,
        True,
    ),
}
"""scipy's pairs as :func:`_integrate` takes them: A, B, C, the estimators, their order."""


def compiled_solver(rhs, y0: np.ndarray, span: float, method: str) -> Solve:
    """scipy's ``method`` (a key of :data:`PAIRS`) from ``y0`` over ``span`` seconds,
    compiled end to end with ``rhs``."""
    a, b, c, e5, e3, order, dop853 = PAIRS[method]
    a = np.ascontiguousarray(a, dtype=float)  # RK45's omits its last, empty column

    def solve(rtol: float) -> tuple[np.ndarray, int]:
        y, evals = _integrate(
            rhs,
            memory(),
            np.array(y0, dtype=float),
            span,
            rtol,
            rtol / 100,
            a,
            b,
            c,
            e5,
            e3,
            order,
            dop853,
        )
        if evals < 0:
            raise ArithmeticError(f"compiled {method} at rtol {rtol:g}: the step became too small")
        return y, evals

    return solve


def compile_seconds(*calls: Callable[[], object]) -> float:
    """CPU seconds of each call's first run, less a second run of it: the compilation."""
    total = 0.0
    for call in calls:
        start = time.process_time()
        call()
        first = time.process_time() - start
        start = time.process_time()
        call()
        total += max(0.0, first - (time.process_time() - start))
    return total
