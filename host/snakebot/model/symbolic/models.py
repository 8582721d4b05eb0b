"""The control vector fields and their Lie brackets, symbolically (sympy).

The thesis derived these in Maple; here they come from the constraint equations of
``docs/models.md`` with sympy. Conventions:

* Lie bracket ``[X, Y](q) = DY(q) X(q) - DX(q) Y(q)`` (the thesis's Definition 3).
* 3-link snake: ``q = (x, y, theta, phi1, phi2)``, joint-velocity inputs, fields in
  the thesis's order g1, g2, h1 = [g1, g2], h2 = [g1, h1], h3 = [g2, h1].
* Trident: ``q = (x, y, theta, phi1, phi2, phi3)``, body-velocity inputs (``form="body"``,
  the thesis's system (18)) or world-velocity inputs (``form="world"``, system (11));
  fields g1, g2, g3, h1 = [g1, g2], h2 = [g1, g3], h3 = [g2, g3].
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import sympy as sp

FORMS = ("body", "world")


@dataclass(frozen=True)
class SymbolicModel:
    """Fields of one model: ``fields`` maps names (g1, ..., h1, ...) to column matrices."""

    name: str
    form: str
    q: tuple[sp.Symbol, ...]
    params: tuple[sp.Symbol, ...]
    fields: dict[str, sp.Matrix]
    brackets: dict[str, tuple[str, str]]  # h name -> (X, Y) with h = [X, Y]
    det_b: sp.Expr | None  # determinant whose zero set is the singular set (3-link only)

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(n for n in self.fields if n.startswith("g"))

    @property
    def filtration(self) -> tuple[tuple[str, ...], ...]:
        """Field names added at each step of the filtration Delta_1, Delta_2, ..."""
        steps: list[tuple[str, ...]] = [self.inputs]
        depth: dict[str, int] = {g: 1 for g in self.inputs}
        for h, (a, b) in self.brackets.items():
            depth[h] = depth[a] + depth[b]
        for level in range(2, max(depth.values()) + 1):
            steps.append(tuple(n for n, d in depth.items() if d == level))
        return tuple(steps)


def lie_bracket(x: sp.Matrix, y: sp.Matrix, q: sp.Matrix) -> sp.Matrix:
    """``[X, Y] = DY X - DX Y``."""
    return y.jacobian(q) * x - x.jacobian(q) * y


def _rotation(theta: sp.Expr) -> sp.Matrix:
    return sp.Matrix([[sp.cos(theta), -sp.sin(theta)], [sp.sin(theta), sp.cos(theta)]])


@cache
def snake3() -> SymbolicModel:
    """The 3-link snake (models.md): (xb, yb, dtheta) = -B^-1 C (u1, u2), rotated to the world."""
    x, y, theta, p1, p2 = sp.symbols("x y theta phi1 phi2", real=True)
    l = sp.Symbol("l", positive=True)  # noqa: E741 - the thesis's symbol
    q = sp.Matrix([x, y, theta, p1, p2])
    b = sp.Matrix(
        [
            [0, 1, l],
            [-sp.sin(p1), sp.cos(p1), l * (1 + 2 * sp.cos(p1))],
            [-sp.sin(p1 + p2), sp.cos(p1 + p2), l * (1 + 2 * sp.cos(p2) + 2 * sp.cos(p1 + p2))],
        ]
    )
    c = sp.Matrix([[0, 0], [l, 0], [l * (1 + 2 * sp.cos(p2)), l]])
    det_b = l * (sp.sin(p1) - sp.sin(p2) + sp.sin(p1 - p2))
    body = -(b.adjugate() * c) / det_b  # B^-1 = adj(B) / det(B)
    fields: dict[str, sp.Matrix] = {}
    for i in range(2):
        planar = _rotation(theta) * body[0:2, i]
        joints = [int(i == 0), int(i == 1)]
        fields[f"g{i + 1}"] = sp.Matrix([planar[0], planar[1], body[2, i], *joints])
    brackets = {"h1": ("g1", "g2"), "h2": ("g1", "h1"), "h3": ("g2", "h1")}
    for h, (a, bb) in brackets.items():
        fields[h] = lie_bracket(fields[a], fields[bb], q)
    return SymbolicModel("snake3", "joint", tuple(q), (l,), fields, brackets, det_b)


@cache
def trident(form: str = "body") -> SymbolicModel:
    """The trident (models.md): dphi_i = (sin nu_i u1 - cos nu_i u2 - (r cos phi_i + l) u3) / l."""
    if form not in FORMS:
        raise ValueError(f"form must be one of {FORMS}, not {form!r}")
    x, y, theta = sp.symbols("x y theta", real=True)
    phis = sp.symbols("phi1 phi2 phi3", real=True)
    r = sp.Symbol("r", nonnegative=True)
    l = sp.Symbol("l", positive=True)  # noqa: E741
    alphas = sp.symbols("alpha1 alpha2 alpha3", real=True)
    q = sp.Matrix([x, y, theta, *phis])
    if form == "body":
        planar = _rotation(theta)  # (dx, dy) = R(theta) (u1, u2)
        nus = [a + p for a, p in zip(alphas, phis, strict=True)]
    else:
        planar = sp.eye(2)  # (dx, dy) = (u1, u2)
        nus = [theta + a + p for a, p in zip(alphas, phis, strict=True)]
    columns = []
    for i in range(3):
        top = [planar[0, i], planar[1, i], 0] if i < 2 else [0, 0, 1]
        if i == 0:
            joints = [sp.sin(nu) / l for nu in nus]
        elif i == 1:
            joints = [-sp.cos(nu) / l for nu in nus]
        else:
            joints = [-(r * sp.cos(p) + l) / l for p in phis]
        columns.append(sp.Matrix(top + joints))
    fields = {f"g{i + 1}": col for i, col in enumerate(columns)}
    brackets = {"h1": ("g1", "g2"), "h2": ("g1", "g3"), "h3": ("g2", "g3")}
    for h, (a, b) in brackets.items():
        fields[h] = lie_bracket(fields[a], fields[b], q)
    return SymbolicModel("trident", form, tuple(q), (r, l, *alphas), fields, brackets, None)


@cache
def car() -> SymbolicModel:
    """The car of the thesis's first chapter: q = (x, y, theta, Phi), steering
    S = d/dPhi, drive D = cos theta d/dx + sin theta d/dy + tan(Phi) / L d/dtheta;
    R = [S, D] and T = [R, D] (kinematics/lie.py computes the same numerically)."""
    x, y, theta, steer = sp.symbols("x y theta Phi", real=True)
    wheelbase = sp.Symbol("L", positive=True)
    q = sp.Matrix([x, y, theta, steer])
    fields = {
        "S": sp.Matrix([0, 0, 0, 1]),
        "D": sp.Matrix([sp.cos(theta), sp.sin(theta), sp.tan(steer) / wheelbase, 0]),
    }
    brackets = {"R": ("S", "D"), "T": ("R", "D")}
    for h, (a, b) in brackets.items():
        fields[h] = lie_bracket(fields[a], fields[b], q)
    return SymbolicModel("car", "car", tuple(q), (wheelbase,), fields, brackets, None)


def model_for(kind: str, links: int = 3, form: str = "body") -> SymbolicModel:
    """The symbolic model for a robot kind: the 3-link snake and the trident (other
    snakes' fields are computed numerically with exact derivatives: kinematics.lie)."""
    if kind == "trident":
        return trident(form)
    if kind == "snake" and links == 3:
        return snake3()
    if kind == "car":
        return car()
    raise ValueError(f"no symbolic model for a {links}-link {kind}: see kinematics.lie")
