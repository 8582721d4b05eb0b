"""A Python counterpart of the quasi-static Coulomb wheel model (docs/models.md, "The
general model") for an N-link snake under a sines joint schedule, written from the
documented model for bench_kinematics.py to race the C core against.

The body velocity ``xi = (dx, dy, dtheta)`` minimises the wheels' frictional power

    f(xi) = sum_i  lateral_i |n_i . v_i|  +  rolling_i |t_i . v_i|

with every wheel's velocity ``v_i`` affine in ``xi``; the weights are the robot's
``wheel_friction_n()`` (normal loads from the masses). ``f`` is convex and piecewise
linear, an L1 fit in three unknowns, so its minimum is at a vertex where three of the
``2 N`` terms vanish: the sticking wheel directions. Two right-hand sides find it:

- numpy: every vertex at once (the triples' 3x3 systems by Cramer's rule, stacked),
  the one with the least power kept;
- plain ``math``: the last optimal vertices first, then the last one's neighbours,
  each accepted when it passes the optimality test of a convex function (zero is a
  subgradient: the three sticking directions can balance the sliding ones' forces with
  multipliers within friction, ``|y| <= 1``); only if none does, every vertex, as numpy
  does. Most calls of an integrator are a single test.

Both are exact (the minimiser, not an approximation of it), so they agree with each
other, with the C core and with a linear programme solved by HiGHS (``lp_body_velocity``,
the independent check) to rounding wherever the minimum is one point. Where it is an
edge (concurrent axles whose rolling resistances balance) the model takes the edge's
centre; the benchmark's gait never meets one, so that rule is not written here.

Wheel velocities come from differentiating the wheel positions along the chain: link
``k`` has heading ``psi_k = theta + phi_1 + .. + phi_(k-1)`` and its wheel sits at
``W_k = p + sum_(m<k) 2 l e(psi_m) + l e(psi_k)``, so with ``e'(a) = (-sin a, cos a)``

    v_k = (dx, dy) + sum_(m<k) 2 l psi'_m e'(psi_m) + l psi'_k e'(psi_k),
    psi'_m = dtheta + s_m,  s_m = dphi_1 + .. + dphi_(m-1),

whose parts in ``dtheta`` (``G_k``) and in the joint rates (``H_k``) are running sums
along the chain; ``n_k = e'(psi_k)``, ``t_k = e(psi_k)``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator

import numpy as np
from scipy.optimize import linprog

from snakebot.model.kinematics import Sines
from snakebot.model.robots.model import Robot

#: A vertex whose three rows are this close to dependent (|det| over the product of
#: their lengths) is skipped: it fixes no point.
DEPENDENT = 1e-12
#: Multipliers this far past 1 still pass the optimality test (rounding).
CERTIFY = 1e-9
#: How many of the last optimal vertices the math right-hand side tests first.
RECENT = 4


def schedule(gait: Sines, t: float) -> tuple[list[float], list[float]]:
    """The joint angles and rates at ``t`` (phi_j = offset_j + rate_j t + amp_j sin(w t
    + phase_j))."""
    m = len(gait.amp)
    offset = gait.offset or (0.0,) * m
    rate = gait.rate or (0.0,) * m
    phi, dphi = [], []
    for j in range(m):
        arg = gait.omega * t + gait.phase[j]
        phi.append(offset[j] + rate[j] * t + gait.amp[j] * math.sin(arg))
        dphi.append(rate[j] + gait.amp[j] * gait.omega * math.cos(arg))
    return phi, dphi


class Snake:
    """The snake's constants: half-link, links, the rows' weights, the vertex triples."""

    def __init__(self, robot: Robot, gait: Sines) -> None:
        if robot.kind != "snake":
            raise ValueError(f"{robot.name} is not a snake")
        self.gait = gait
        self.l = robot.l
        self.links = robot.links
        lateral, rolling = robot.wheel_friction_n()
        # Rows 2k (across wheel k) and 2k + 1 (along it).
        self.weights = np.column_stack((lateral, rolling)).ravel()
        self.weight_list = [float(w) for w in self.weights]
        self.triples = list(itertools.combinations(range(2 * self.links), 3))
        self.triple_index = np.array(self.triples)
        self.adjacent = {triple: self.neighbours(triple) for triple in self.triples}
        self.y0 = np.zeros(3)

    # ---- numpy: the rows as arrays, every vertex at once ----

    def rows_numpy(self, t: float, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(A, c): the rows' speeds are A xi + c, A of shape (2 N, 3)."""
        m = self.gait
        arg = m.omega * t + np.asarray(m.phase)
        phi = np.asarray(m.offset or 0.0) + np.asarray(m.rate or 0.0) * t + np.sin(arg) * m.amp
        dphi = np.asarray(m.rate or 0.0) + np.cos(arg) * (np.asarray(m.amp) * m.omega)
        psi = pose[2] + np.concatenate(([0.0], np.cumsum(phi)))
        s = np.concatenate(([0.0], np.cumsum(dphi)))
        cos, sin = np.cos(psi), np.sin(psi)
        perp = np.column_stack((-sin, cos))  # e'(psi_k) = n_k
        along = np.column_stack((cos, sin))  # t_k
        # G_k = sum_(m<k) 2 l e'_m + l e'_k; H_k the same with each term times s_m.
        g = np.cumsum(2 * self.l * perp, axis=0) - self.l * perp
        h = np.cumsum((2 * self.l * s)[:, None] * perp, axis=0) - (self.l * s)[:, None] * perp
        a = np.empty((2 * self.links, 3))
        c = np.empty(2 * self.links)
        a[0::2, :2], a[1::2, :2] = perp, along
        a[0::2, 2] = np.einsum("ij,ij->i", perp, g)
        a[1::2, 2] = np.einsum("ij,ij->i", along, g)
        c[0::2] = np.einsum("ij,ij->i", perp, h)
        c[1::2] = np.einsum("ij,ij->i", along, h)
        return a, c

    def minimise_numpy(self, a: np.ndarray, c: np.ndarray) -> np.ndarray:
        """The least-power vertex over all triples of rows."""
        systems = a[self.triple_index]  # (triples, 3, 3)
        det = np.linalg.det(systems)
        size = np.sqrt(np.einsum("tij,tij->ti", systems, systems).prod(axis=1))
        keep = np.abs(det) > DEPENDENT * size
        xs = np.linalg.solve(systems[keep], -c[self.triple_index[keep], None])[..., 0]
        power = np.abs(xs @ a.T + c) @ self.weights
        return xs[np.argmin(power)]

    def rhs_numpy(self, t: float, pose: np.ndarray) -> np.ndarray:
        return self.minimise_numpy(*self.rows_numpy(t, pose))

    # ---- plain math: the rows as lists, the last vertex tested first ----

    def rows_math(self, t: float, pose: list[float]) -> list[tuple[float, float, float, float]]:
        """Each row as (a_x, a_y, a_theta, c): its speed is a . xi + c."""
        phi, dphi = schedule(self.gait, t)
        two_l, half = 2.0 * self.l, self.l
        psi, s = pose[2], 0.0
        gx = gy = hx = hy = 0.0  # the running sums over the links before this one
        rows = []
        for k in range(self.links):
            if k:
                psi += phi[k - 1]
                s += dphi[k - 1]
            cs, sn = math.cos(psi), math.sin(psi)
            g_x, g_y = gx - half * sn, gy + half * cs
            h_x, h_y = hx - half * s * sn, hy + half * s * cs
            rows.append((-sn, cs, cs * g_y - sn * g_x, cs * h_y - sn * h_x))
            rows.append((cs, sn, cs * g_x + sn * g_y, cs * h_x + sn * h_y))
            gx, gy = gx - two_l * sn, gy + two_l * cs
            hx, hy = hx - two_l * s * sn, hy + two_l * s * cs
        return rows

    @staticmethod
    def vertex(rows, triple) -> tuple[float, float, float, float, list[float]] | None:  # noqa: ANN001
        """The point where the triple's rows vanish, with the determinant and the inverse's
        columns (flattened: column j moves row triple[j] by 1); None if they are dependent."""
        (ax, ay, az, ac), (bx, by, bz, bc), (cx, cy, cz, cc) = (rows[i] for i in triple)
        # Cofactors: column j of the inverse is (row_{j+1} x row_{j+2}) / det.
        u = (by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx)
        v = (cy * az - cz * ay, cz * ax - cx * az, cx * ay - cy * ax)
        w = (ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx)
        det = ax * u[0] + ay * u[1] + az * u[2]
        size = math.sqrt(
            (ax * ax + ay * ay + az * az)
            * (bx * bx + by * by + bz * bz)
            * (cx * cx + cy * cy + cz * cz)
        )
        if not abs(det) > DEPENDENT * size:
            return None
        x = (-(ac * u[0] + bc * v[0] + cc * w[0]) / det, -(ac * u[1] + bc * v[1] + cc * w[1]) / det)
        z = -(ac * u[2] + bc * v[2] + cc * w[2]) / det
        return x[0], x[1], z, det, [*u, *v, *w]

    def power(self, rows, x: float, y: float, z: float) -> float:  # noqa: ANN001
        return sum(
            wt * abs(ax * x + ay * y + az * z + ac)
            for wt, (ax, ay, az, ac) in zip(self.weight_list, rows, strict=True)
        )

    def optimal(self, rows, triple, found) -> bool:  # noqa: ANN001
        """Zero is a subgradient at the vertex: the forces of the sliding rows (weight times
        the sign of the speed) balanced by the triple's within friction. A row off the
        triple that also vanishes (a degenerate vertex) fails the test: enumerate."""
        x, y, z, det, inv = found
        gx = gy = gz = 0.0
        scale = max(abs(r[3]) for r in rows) + max(abs(x), abs(y), abs(z)) * max(
            max(abs(r[0]), abs(r[1]), abs(r[2])) for r in rows
        )
        for k, (ax, ay, az, ac) in enumerate(rows):
            if k in triple:
                continue
            speed = ax * x + ay * y + az * z + ac
            if abs(speed) <= 1e-12 * scale:
                return False
            f = self.weight_list[k] if speed > 0.0 else -self.weight_list[k]
            gx, gy, gz = gx + f * ax, gy + f * ay, gz + f * az
        # The triple's forces F_j solve sum_j F_j a_j = -g: F = -(M^T g), M = A_S^-1.
        for j, k in enumerate(triple):
            force = -(inv[3 * j] * gx + inv[3 * j + 1] * gy + inv[3 * j + 2] * gz) / det
            if abs(force) > self.weight_list[k] * (1.0 + CERTIFY):
                return False
        return True

    def certified(self, rows, triple):  # noqa: ANN001, ANN205
        """The triple's vertex if it passes the optimality test, else None."""
        found = self.vertex(rows, triple)
        return found if found is not None and self.optimal(rows, triple, found) else None

    def neighbours(self, triple: tuple[int, ...]) -> list[tuple[int, ...]]:
        """The triples sharing two rows with ``triple``: the vertices one edge away."""
        return [
            tuple(sorted((*(r for r in triple if r != out), new)))
            for out in triple
            for new in range(len(self.weight_list))
            if new not in triple
        ]

    def candidates(self, recent: list[tuple[int, ...]]) -> Iterator[tuple[int, ...]]:
        yield from recent
        if recent:
            yield from self.adjacent[recent[0]]

    def rhs_math_factory(self) -> Callable[[float, np.ndarray], list[float]]:
        """The math right-hand side, with its own memory of the last few optimal
        vertices: those are tested first, then the last one's neighbours (where the
        sticking set changes along a path, the new vertex shares an edge with the old),
        each accepted only if it passes the optimality test, and only then every vertex
        compared."""
        recent: list[tuple[int, ...]] = []

        def remember(triple: tuple[int, ...]) -> None:
            if triple in recent:
                recent.remove(triple)
            recent.insert(0, triple)
            del recent[RECENT:]

        def rhs(t: float, pose: np.ndarray) -> list[float]:
            rows = self.rows_math(t, pose.tolist())
            for triple in self.candidates(recent):
                found = self.certified(rows, triple)
                if found is not None:
                    remember(triple)
                    return list(found[:3])
            best, best_power = None, math.inf
            for triple in self.triples:
                found = self.vertex(rows, triple)
                if found is not None:
                    p = self.power(rows, *found[:3])
                    if p < best_power:
                        best, best_power = (triple, found), p
            if best is None:
                raise ArithmeticError(f"the wheels fix no body velocity at t={t}")
            remember(best[0])
            return list(best[1][:3])

        return rhs

    # ---- the independent check: a linear programme ----

    def lp_body_velocity(self, t: float, pose: np.ndarray) -> np.ndarray:
        """The same minimum by HiGHS: min w . e subject to -e <= A xi + c <= e."""
        a, c = self.rows_numpy(t, pose)
        m = len(c)
        res = linprog(
            np.concatenate((np.zeros(3), self.weights)),
            A_ub=np.block([[a, -np.eye(m)], [-a, -np.eye(m)]]),
            b_ub=np.concatenate((-c, c)),
            bounds=[(None, None)] * 3 + [(0, None)] * m,
            method="highs",
        )
        if res.status != 0:
            raise ArithmeticError(f"HiGHS found no minimum at t={t}: {res.message}")
        return res.x[:3]
