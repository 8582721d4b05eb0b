"""Planar poses (x, y, theta) as elements of SE(2): composition, inverse, and the k-th
root along the screw motion (the one-parameter subgroup) through a pose.

A pose ``b`` composed onto ``a`` is ``b`` expressed in ``a``'s frame, as ``sim predict``
reports a displacement: x along the start heading, y to its left, theta
counter-clockwise. Theta is not wrapped: a pose that turns 2 pi is not the identity's
root."""

from __future__ import annotations

import math

import numpy as np


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a`` then ``b`` (``b`` given in ``a``'s frame)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]])


def inverse(a: np.ndarray) -> np.ndarray:
    """The pose that undoes ``a``."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2]])


def relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``b`` seen from ``a``: the displacement that takes ``a`` to ``b``."""
    return compose(inverse(a), b)


def _v(theta: float) -> np.ndarray:
    """The matrix that turns a twist's linear part into the translation it produces
    while the heading turns by ``theta`` at a steady rate."""
    if abs(theta) < 1e-9:
        return np.eye(2)
    s, c = math.sin(theta) / theta, (1.0 - math.cos(theta)) / theta
    return np.array([[s, -c], [c, s]])


def root(g: np.ndarray, k: int) -> np.ndarray:
    """The pose whose k-fold composition is ``g``: a k-th of the same circular arc."""
    linear = np.linalg.solve(_v(g[2]), g[:2]) / k
    theta = g[2] / k
    return np.r_[_v(theta) @ linear, theta]


def power(g: np.ndarray, k: int) -> np.ndarray:
    """``g`` composed with itself ``k`` times."""
    out = np.zeros(3)
    for _ in range(k):
        out = compose(out, g)
    return out
