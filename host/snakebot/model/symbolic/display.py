"""Readable expressions of the fields for ``snakebot model fields --symbolic``."""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

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


def field_expressions(robot: Robot, form: str = "body") -> Expressions:
    """The robot's fields, simplified. Lengths stay symbolic (l, r); the trident's corner
    angles are the robot's. The 3-link snake's fields are invariant under rigid motions,
    so they are shown at theta = 0 (x, y in link 1's frame); simplifying them takes
    about 20 seconds."""
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
        components[name] = [sp.factor(sp.trigsimp(sp.together(c.subs(subs)))) for c in vec]
    return Expressions(model, components, frame)
