"""Truncated multivariate Taylor polynomials ("jets") for exact derivatives of any order.

A jet of degree K in m variables holds the Taylor coefficients of a function at a point,
up to total degree K, one coefficient per monomial; monomials are sorted by total
degree, so truncating to degree k keeps a prefix. Arithmetic, sin, cos and division
follow the chain rule exactly (no finite differences), and a partial derivative lowers
the degree by one. The Lie brackets of fields written with jets are therefore exact to
rounding, to any depth the degree allows (kinematics/lie.py).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from functools import cache

import numpy as np


@cache
def _monomials(m: int, degree: int) -> tuple[tuple[int, ...], ...]:
    """Exponent tuples of total degree <= degree, sorted by total degree."""
    out: list[tuple[int, ...]] = []
    for total in range(degree + 1):
        for combo in itertools.combinations_with_replacement(range(m), total):
            e = [0] * m
            for v in combo:
                e[v] += 1
            out.append(tuple(e))
    return tuple(out)


@dataclass(frozen=True)
class JetSpace:
    """The monomials of m variables up to ``degree`` and the index tables for products
    and partial derivatives."""

    m: int
    degree: int
    sizes: tuple[int, ...] = field(init=False)  # sizes[k]: monomials of degree <= k
    _tables: dict[str, object] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        mons = _monomials(self.m, self.degree)
        index = {e: i for i, e in enumerate(mons)}
        deg = np.array([sum(e) for e in mons])
        sizes = tuple(int(np.count_nonzero(deg <= k)) for k in range(self.degree + 1))
        # Products: pairs (i, j) whose product has degree <= K, sorted by the target.
        left, right, target = [], [], []
        for i, a in enumerate(mons):
            for j, b in enumerate(mons[: sizes[self.degree - deg[i]]]):
                left.append(i)
                right.append(j)
                target.append(index[tuple(x + y for x, y in zip(a, b, strict=True))])
        order = np.argsort(np.array(target), kind="stable")
        left_a, right_a = np.array(left)[order], np.array(right)[order]
        target_a = np.array(target)[order]
        # Partial derivatives: d/dv of monomial a is a_v times the monomial a - e_v.
        deriv = []
        for v in range(self.m):
            src, dst, fac = [], [], []
            for i, a in enumerate(mons):
                if a[v] > 0:
                    lower = list(a)
                    lower[v] -= 1
                    src.append(i)
                    dst.append(index[tuple(lower)])
                    fac.append(float(a[v]))
            deriv.append((np.array(src, int), np.array(dst, int), np.array(fac)))
        object.__setattr__(self, "sizes", sizes)
        object.__setattr__(
            self,
            "_tables",
            {"left": left_a, "right": right_a, "target": target_a, "deriv": deriv},
        )

    def product_tables(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(left, right, reduce starts, targets) for a product truncated to degree k."""
        key = f"product{k}"
        if key not in self._tables:
            t = self._tables
            keep = t["target"] < self.sizes[k]  # type: ignore[operator]
            left, right = t["left"][keep], t["right"][keep]  # type: ignore[index]
            target = t["target"][keep]  # type: ignore[index]
            starts = np.flatnonzero(np.r_[True, target[1:] != target[:-1]])
            self._tables[key] = (left, right, starts, target[starts])
        return self._tables[key]  # type: ignore[return-value]

    def variable(self, v: int, value: float, degree: int | None = None) -> Jet:
        """The jet of the coordinate x_v at x_v = value."""
        k = self.degree if degree is None else degree
        c = np.zeros(self.sizes[k])
        c[0] = value
        if k >= 1:
            c[1 + v] = 1.0  # the degree-1 monomials follow the constant, in variable order
        return Jet(self, c)

    def constant(self, value: float, degree: int | None = None) -> Jet:
        c = np.zeros(self.sizes[self.degree if degree is None else degree])
        c[0] = value
        return Jet(self, c)


class Jet:
    """Taylor coefficients of one function up to some degree (see the module doc)."""

    __slots__ = ("space", "c")

    def __init__(self, space: JetSpace, c: np.ndarray) -> None:
        self.space = space
        self.c = c

    @property
    def degree(self) -> int:
        return self.space.sizes.index(len(self.c))

    @property
    def value(self) -> float:
        return float(self.c[0])

    def truncate(self, k: int) -> Jet:
        return Jet(self.space, self.c[: self.space.sizes[k]])

    def _other(self, other: Jet | float) -> tuple[np.ndarray, np.ndarray]:
        if isinstance(other, Jet):
            n = min(len(self.c), len(other.c))
            return self.c[:n], other.c[:n]
        b = np.zeros_like(self.c)
        b[0] = other
        return self.c, b

    def __add__(self, other: Jet | float) -> Jet:
        a, b = self._other(other)
        return Jet(self.space, a + b)

    __radd__ = __add__

    def __sub__(self, other: Jet | float) -> Jet:
        a, b = self._other(other)
        return Jet(self.space, a - b)

    def __rsub__(self, other: Jet | float) -> Jet:
        a, b = self._other(other)
        return Jet(self.space, b - a)

    def __neg__(self) -> Jet:
        return Jet(self.space, -self.c)

    def __mul__(self, other: Jet | float) -> Jet:
        if not isinstance(other, Jet):
            return Jet(self.space, self.c * other)
        k = min(self.degree, other.degree)
        left, right, starts, target = self.space.product_tables(k)
        out = np.zeros(self.space.sizes[k])
        out[target] = np.add.reduceat(self.c[left] * other.c[right], starts)
        return Jet(self.space, out)

    __rmul__ = __mul__

    def __truediv__(self, other: Jet | float) -> Jet:
        if not isinstance(other, Jet):
            return Jet(self.space, self.c / other)
        return self * other.reciprocal()

    def __rtruediv__(self, other: float) -> Jet:
        return self.reciprocal() * other

    def _series(self, coefficients: list[float]) -> Jet:
        """sum_k coefficients[k] h^k with h = self - value (nilpotent: h^(K+1) = 0)."""
        h = self - self.value
        out = self.space.constant(coefficients[0], self.degree)
        power = self.space.constant(1.0, self.degree)
        for coef in coefficients[1:]:
            power = power * h
            out = out + power * coef
        return out

    def reciprocal(self) -> Jet:
        a = self.value
        if a == 0.0:
            raise ZeroDivisionError("jet division by a function that is zero at the point")
        return self._series([(-1.0) ** k / a ** (k + 1) for k in range(self.degree + 1)])

    def sin(self) -> Jet:
        a = self.value
        derivs = [math.sin(a), math.cos(a), -math.sin(a), -math.cos(a)]
        return self._series([derivs[k % 4] / math.factorial(k) for k in range(self.degree + 1)])

    def cos(self) -> Jet:
        a = self.value
        derivs = [math.cos(a), -math.sin(a), -math.cos(a), math.sin(a)]
        return self._series([derivs[k % 4] / math.factorial(k) for k in range(self.degree + 1)])

    def diff(self, v: int) -> Jet:
        """d/dx_v, one degree lower."""
        k = self.degree
        if k == 0:
            raise ValueError("a degree-0 jet has no derivative left")
        src, dst, fac = self.space._tables["deriv"][v]  # type: ignore[index]
        size = self.space.sizes[k - 1]
        out = np.zeros(size)
        keep = src < len(self.c)  # monomials of degree <= k; their derivatives fit size
        np.add.at(out, dst[keep], self.c[src[keep]] * fac[keep])
        return Jet(self.space, out)


def solve(a: list[list[Jet]], b: list[Jet]) -> list[Jet]:
    """Jets of x with A x = b (A square, invertible at the point): x = A0^-1 b refined by
    x <- A0^-1 (b - (A - A0) x), each pass exact to one more degree. LinAlgError where
    A0 is singular."""
    n = len(b)
    k = min([bi.degree for bi in b] + [aij.degree for row in a for aij in row])
    space = b[0].space
    a0 = np.array([[aij.value for aij in row] for row in a])
    lu_inv = np.linalg.inv(a0)
    rest = [[aij.truncate(k) - aij.value for aij in row] for row in a]
    bc = np.array([bi.truncate(k).c for bi in b])
    x = lu_inv @ bc
    for _ in range(k):
        xs = [Jet(space, x[j]) for j in range(n)]
        coupled = [
            sum((rest[i][j] * xs[j] for j in range(n)), space.constant(0.0, k)) for i in range(n)
        ]
        x = lu_inv @ (bc - np.array([c.c for c in coupled]))
    return [Jet(space, x[j]) for j in range(n)]
