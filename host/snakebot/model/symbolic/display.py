"""Readable expressions of the fields for ``snakebot model fields --symbolic``."""

from __future__ import annotations

import random
from dataclasses import dataclass

import sympy as sp
from sympy.simplify.fu import TR8

from snakebot.model.robots import Robot
from snakebot.model.symbolic.models import SymbolicModel, model_for


@dataclass(frozen=True)
class Expressions:
    """Simplified components per field; ``frame`` says how to read x and y."""

    model: SymbolicModel
    components: dict[str, list[sp.Expr]]
    frame: str


def _angle(value: float) -> sp.Expr:
    """An angle as an exact multiple of pi when it is one (to 1e-12)."""
    ratio = sp.nsimplify(value / float(sp.pi), rational=True, tolerance=1e-12)
    return ratio * sp.pi if ratio.q <= 24 else sp.Float(value)


MAX_DET_POWER = 4
"""The highest power of the 3-link snake's determinant a field's denominator holds (its
brackets of order three have the cube)."""


def _over_det(expr: sp.Expr, det: sp.Expr) -> sp.Expr:
    """``expr`` written as a sum of sines and cosines of sums of the angles over a
    rational times a power of ``det``: products turned into sums (fu's TR8), the
    denominator recognised as ``det``'s power by its value at random points. The same
    steps whatever the hash seed (sympy's trigsimp searches in an order that depends on
    it: 15 to more than 240 seconds for the 3-link snake's brackets)."""
    numer, denom = sp.fraction(sp.together(expr))
    numer = sp.factor_terms(sp.expand(TR8(sp.expand(numer))))
    symbols = sorted(denom.free_symbols | det.free_symbols, key=str)
    rng = random.Random(0)
    points = [{s: sp.Float(rng.uniform(0.2, 1.3)) for s in symbols} for _ in range(3)]
    for k in range(MAX_DET_POWER + 1):
        ratios = [complex(sp.N((denom / det**k).subs(p))) for p in points]
        if all(abs(r - ratios[0]) <= 1e-9 * abs(ratios[0]) for r in ratios):
            scale = sp.nsimplify(ratios[0].real, rational=True, tolerance=1e-9)
            return numer / (scale * det**k) if k else numer / scale
    return numer / sp.factor(TR8(sp.expand(denom)))


def field_expressions(robot: Robot, form: str = "body") -> Expressions:
    """The robot's fields, simplified. Lengths stay symbolic (l, r); the trident's corner
    angles are the robot's. The 3-link snake's fields are invariant under rigid motions,
    so they are shown at theta = 0 (x, y in link 1's frame), each a sum of sines and
    cosines over a power of the determinant (:func:`_over_det`; about 5 seconds)."""
    model = model_for(robot.kind, robot.links, form)
    subs: dict[sp.Symbol, sp.Expr] = {}
    frame = "the world frame"
    if model.name == "trident":
        for sym, value in zip(model.params[2:], robot.alphas, strict=True):
            subs[sym] = _angle(value)
    elif model.name == "snake3":
        subs[model.q[2]] = sp.Integer(0)
        frame = (
            "link 1's frame (these are the fields at theta = 0; at any theta, "
            "(dx, dy) = R(theta) (x, y), the rest unchanged)"
        )
    components = {}
    for name, vec in model.fields.items():
        if model.name == "snake3" and model.det_b is not None:
            det = model.det_b / model.params[0]  # its length factor stays with the numerator
            components[name] = [_over_det(c.subs(subs), det) for c in vec]
        else:
            components[name] = [sp.factor(sp.trigsimp(sp.together(c.subs(subs)))) for c in vec]
    return Expressions(model, components, frame)
