"""Control vector fields and their Lie brackets to any depth, for the N-link snake
(N = 3..16) and the car, from jets (exact derivatives; kinematics/jets.py).

Bracket convention: ``[X, Y] = DY X - DX Y`` (the thesis's Definition 3). The brackets
computed are a Lyndon basis of the free Lie algebra on the two inputs (standard
bracketing of the Lyndon words), which spans every step of the filtration: depth 2
``[g1,g2]``; depth 3 ``[g1,[g1,g2]]``, ``[[g1,g2],g2]`` (= -[g2,[g1,g2]]); and so on.

N-link snake: the N wheel constraints ``n_i . v_i = 0`` on q = (x, y, theta, phi1 ..
phi_{N-1}) have rank N, so the admissible velocities form a rank-2 distribution. Its
two control fields are parameterised by the first two joint rates: g_k has
dphi_k = 1, the other of dphi1, dphi2 zero, and (dx, dy, dtheta, dphi3 ..) whatever the
constraints then require. For N = 3 these are the thesis's g1, g2. The first three
wheels fix the body's motion from dphi1, dphi2 (a 3-link snake), and wheel k + 1 then
fixes dphi_k, so for every N the fields are undefined exactly on the 3-link singular
set of the first two joints: phi1 = phi2, or phi1 or phi2 at +-pi.

Car (the thesis's first chapter): q = (x, y, theta, Phi), (x, y) the middle of the rear
axle, theta the heading, Phi the steering angle, L the wheelbase. Steering
``S = d/dPhi``, drive ``D = cos theta d/dx + sin theta d/dy + tan(Phi) / L d/dtheta``;
``R = [S, D] = 1 / (L cos^2 Phi) d/dtheta`` turns on the spot and
``T = [R, D] = (-sin theta d/dx + cos theta d/dy) / (L cos^2 Phi)`` slides sideways:
growth vector (2, 3, 4) wherever |Phi| < pi/2.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from snakebot.errors import InputError
from snakebot.model.kinematics.jets import Jet, JetSpace, solve
from snakebot.model.robots import Robot

#: Rank tolerance on unit-normalised columns (singular values below count as zero).
RANK_TOL = 1e-9
#: Past the exact depths the ranks are numeric, and near the singular set the brackets
#: lose their digits (each depth solves the constraints again, whose conditioning goes
#: as 1 / det B): they are not trusted where the condition number exceeds this, or where
#: a snake's |det B| / l (sin p1 - sin p2 + sin(p1 - p2)) is below UNRELIABLE_DET (the
#: 5-link snake's depth-4 rank comes out wrong at 2e-4 and right at 2e-3).
UNRELIABLE_CONDITION = 1e12
UNRELIABLE_DET = 1e-3
#: Reciprocal condition of the constraints' unknown block below which q is singular.
SINGULAR_RCOND = 1e-12
MAX_DEPTH = 8
#: Most coefficient products one jet product may take (memory and time stay bounded:
#: about 3 s for a 16-link snake at depth 5).
MAX_PRODUCTS = 100_000


class LieError(InputError):
    """Fields asked of a robot or at a depth this module does not provide."""


@dataclass(frozen=True)
class LieModel:
    """Fields as jets: ``build(jets)`` gets the jets of the coordinates in ``depends``
    and returns each input field's components (one jet per coordinate), or None where
    the fields are undefined."""

    robot: str
    coordinates: tuple[str, ...]
    inputs: tuple[str, ...]
    depends: tuple[int, ...]
    build: Callable[[list[Jet]], list[list[Jet]] | None]
    aliases: dict[str, str]
    #: Fields whose first len(basis) coordinates form a matrix with a closed-form
    #: determinant that is non-zero wherever the fields exist, and the growth vector
    #: they give exactly (the ranks at depths 1 .. len(exact)).
    basis: tuple[str, ...]
    exact: tuple[int, ...]
    #: How far q is from the singular set, in the units of UNRELIABLE_DET.
    clearance: Callable[[np.ndarray], float] = lambda q: math.inf


@dataclass(frozen=True)
class LieFields:
    """Fields and brackets at q: ``names`` (inputs, then brackets by depth),
    ``depths``, ``values`` (fields x coordinates; None where singular); ``aliases`` maps
    a bracket expression to the name shown instead (the car's R, T); ``basis`` and
    ``exact`` as in LieModel."""

    robot: str
    q: np.ndarray
    names: tuple[str, ...]
    depths: tuple[int, ...]
    values: np.ndarray | None
    aliases: dict[str, str]
    basis: tuple[str, ...] = ()
    exact: tuple[int, ...] = ()
    basis_values: np.ndarray | None = None  # the basis fields (rows), at any depth asked
    clearance: float = math.inf  # LieModel.clearance at q

    @property
    def singular(self) -> bool:
        return self.values is None

    def __getitem__(self, name: str) -> np.ndarray:
        if self.values is None:
            raise KeyError(f"the fields are undefined at q = {self.q}")
        return self.values[self.names.index(self.aliases.get(name, name))]

    def _residual(self, depth: int) -> np.ndarray:
        """Unit columns of the fields up to ``depth`` outside the basis, with the basis's
        part removed (the Schur complement on the coordinates past the basis's): their
        rank is what the fields add to the basis's."""
        assert self.values is not None
        span = len(self.basis)
        assert self.basis_values is not None
        top = self.basis_values[:, :span].T  # invertible, exactly
        low = self.basis_values[:, span:].T
        extra = [
            self.values[i]
            for i, d in enumerate(self.depths)
            if d <= depth and self.names[i] not in self.basis
        ]
        if not extra or span == self.values.shape[1]:
            return np.zeros((0, 0))
        cols = np.array(extra).T
        rest = cols[span:] - low @ np.linalg.solve(top, cols[:span])
        return rest / np.maximum(np.linalg.norm(cols, axis=0), 1e-300)

    @property
    def growth(self) -> tuple[int, ...] | None:
        """Rank of Delta_1 .. Delta_depth. Up to len(exact) the ranks are exact (a
        closed-form determinant, see lie_model); beyond, the basis's rank plus the
        numeric rank (unit columns, RANK_TOL) of what the deeper brackets add."""
        if self.values is None:
            return None
        ranks = []
        for k in range(1, max(self.depths) + 1):
            if k <= len(self.exact):
                ranks.append(self.exact[k - 1])
                continue
            rest = self._residual(k)
            sv = np.linalg.svd(rest, compute_uv=False) if rest.size else np.zeros(0)
            ranks.append(len(self.basis) + int(np.count_nonzero(sv > RANK_TOL)))
        return tuple(ranks)

    @property
    def ranks_reliable(self) -> bool | None:
        """False where some rank is numeric (past the exact depths) and the condition
        number exceeds UNRELIABLE_CONDITION: near the singular set, double precision
        cannot decide it."""
        if self.values is None:
            return None
        if max(self.depths) <= len(self.exact):
            return True
        return (self.condition or 0.0) < UNRELIABLE_CONDITION and (self.clearance >= UNRELIABLE_DET)

    @property
    def condition(self) -> float | None:
        """How near the ranks are to changing: the condition number of the basis's block
        (unit columns; exact rank, but it says how near q is to the singular set) or, if
        larger, the largest over the smallest kept singular value of what the deeper
        brackets add."""
        if self.values is None:
            return None
        assert self.basis_values is not None
        top = self.basis_values[:, : len(self.basis)].T
        worst = float(np.linalg.cond(top / np.linalg.norm(top, axis=0)))
        rest = self._residual(max(self.depths))
        if rest.size:
            sv = np.linalg.svd(rest, compute_uv=False)
            kept = sv[sv > RANK_TOL]
            if kept.size:
                worst = max(worst, float(kept[0] / kept[-1]))
        return worst


def lyndon_words(letters: int, depth: int) -> list[tuple[int, ...]]:
    """Lyndon words over 0..letters-1 up to length depth, by length (Duval)."""
    words: list[tuple[int, ...]] = []
    w = [-1]
    while w:
        w[-1] += 1
        words.append(tuple(w))
        m = len(w)
        while len(w) < depth:
            w.append(w[len(w) - m])
        while w and w[-1] == letters - 1:
            w.pop()
    return sorted(words, key=len)


def _is_lyndon(w: tuple[int, ...]) -> bool:
    return all(w < w[k:] for k in range(1, len(w)))


def _name(word: tuple[int, ...], inputs: tuple[str, ...]) -> str:
    if len(word) == 1:
        return inputs[word[0]]
    u, v = _standard(word)
    return f"[{_name(u, inputs)},{_name(v, inputs)}]"


def _standard(word: tuple[int, ...]) -> tuple[tuple[int, ...], tuple[int, ...]]:
    for i in range(1, len(word)):
        if _is_lyndon(word[i:]):
            return word[:i], word[i:]
    raise ValueError(f"{word} is not a Lyndon word")


def _bracket(x: list[Jet], y: list[Jet], depends: tuple[int, ...]) -> list[Jet]:
    """[X, Y]_c = sum_v X_v dY_c/dq_v - Y_v dX_c/dq_v, one degree lower."""
    out = []
    for c in range(len(x)):
        total: Jet | None = None
        for k, v in enumerate(depends):
            term = x[v] * y[c].diff(k) - y[v] * x[c].diff(k)
            total = term if total is None else total + term
        assert total is not None
        out.append(total)
    return out


def lie_fields(model: LieModel, q: np.ndarray, depth: int = 3) -> LieFields:
    """The inputs and a Lyndon basis of brackets up to ``depth`` at q."""
    if not 1 <= depth <= MAX_DEPTH:
        raise LieError(f"the bracket depth must be between 1 and {MAX_DEPTH}, not {depth}").about(
            "depth"
        )
    m = len(model.depends)
    most = MAX_DEPTH
    while most > 1 and math.comb(2 * m + most - 1, most - 1) > MAX_PRODUCTS:
        most -= 1
    if depth > most:
        raise LieError(
            f"depth {depth} for {model.robot} needs derivatives of order {depth - 1} in {m} "
            f"variables, more than this tool computes: ask for depth {most} or less"
        )
    q = np.asarray(q, dtype=float)
    asked = depth
    depth = max(depth, len(model.exact))  # the exact basis's brackets are needed anyway
    words = lyndon_words(len(model.inputs), depth)
    names = tuple(model.aliases.get(n, n) for n in (_name(w, model.inputs) for w in words))
    depths = tuple(len(w) for w in words)
    shown = [i for i, d in enumerate(depths) if d <= asked]
    space = JetSpace(len(model.depends), depth - 1)
    base = model.build([space.variable(k, q[v]) for k, v in enumerate(model.depends)])
    if base is None:
        return LieFields(
            model.robot,
            q,
            tuple(names[i] for i in shown),
            tuple(depths[i] for i in shown),
            None,
            model.aliases,
        )

    memo: dict[tuple[int, ...], list[Jet]] = {(i,): f for i, f in enumerate(base)}
    for w in words:
        if len(w) == 1:
            continue
        u, v = _standard(w)
        keep = depth - len(w) + 1
        memo[w] = _bracket(
            [j.truncate(keep) for j in memo[u]], [j.truncate(keep) for j in memo[v]], model.depends
        )
    values = np.array([[j.value for j in memo[w]] for w in words])
    return LieFields(
        model.robot,
        q,
        tuple(names[i] for i in shown),
        tuple(depths[i] for i in shown),
        values[shown],
        model.aliases,
        model.basis,
        model.exact[:asked],
        values[[names.index(n) for n in model.basis]],
        model.clearance(q),
    )


def _snake(robot: Robot) -> Callable[[list[Jet]], list[list[Jet]] | None]:
    """The N-link snake's two fields (see the module doc) as jets of (theta, phi..)."""
    n_links, half = robot.links, robot.l

    def build(jets: list[Jet]) -> list[list[Jet]] | None:
        theta, phi = jets[0], jets[1:]
        space = theta.space
        zero = space.constant(0.0)
        # psi_i: heading of link i; rel[i][a] = psi_i - psi_a.
        psi = [theta]
        for p in phi:
            psi.append(psi[-1] + p)
        cos_rel = {(i, a): (psi[i] - psi[a]).cos() for i in range(n_links) for a in range(i)}

        def lever(i: int, j: int) -> Jet:
            """Coefficient of joint j's rate (j = -1: dtheta) in wheel i's normal speed."""
            if j >= i:
                return zero
            total = space.constant(half)
            for a in range(max(j + 1, 0), i):
                total = total + cos_rel[(i, a)] * (2.0 * half)
            return total

        rows = []
        for i in range(n_links):
            rows.append(
                [-psi[i].sin(), psi[i].cos(), *(lever(i, j) for j in range(-1, n_links - 1))]
            )
        # columns: dx, dy, dtheta, dphi1, dphi2, dphi3..; unknowns all but dphi1, dphi2
        unknown = [0, 1, 2, *range(5, n_links + 2)]
        a = [[row[c] for c in unknown] for row in rows]
        a0 = np.array([[x.value for x in r] for r in a])
        if 1.0 / np.linalg.cond(a0) < SINGULAR_RCOND:
            return None
        fields = []
        for k in (3, 4):
            z = solve(a, [-row[k] for row in rows])
            vec: list[Jet] = [zero] * (n_links + 2)
            for c, zc in zip(unknown, z, strict=True):
                vec[c] = zc
            vec[k] = space.constant(1.0)
            fields.append(vec)
        return fields

    return build


def _car(robot: Robot) -> Callable[[list[Jet]], list[list[Jet]] | None]:
    wheelbase = robot.l

    def build(jets: list[Jet]) -> list[list[Jet]] | None:
        theta, steer = jets
        space = theta.space
        if abs(np.cos(steer.value)) < 1e-12:
            return None  # tan Phi has a pole: the front wheels are across the car
        zero, one = space.constant(0.0), space.constant(1.0)
        drive = [theta.cos(), theta.sin(), steer.sin() / steer.cos() / wheelbase, zero]
        return [[zero, zero, zero, one], drive]

    return build


def lie_model(robot: Robot) -> LieModel:
    """The jet model of an N-link snake (N >= 3) or a car."""
    names = robot.state_names
    if robot.kind == "car":
        # det(S, D, R, T) = 1 / (L^2 cos^4 Phi): never zero where D exists.
        aliases = {"[S,D]": "R", "[[S,D],D]": "T"}
        basis = ("S", "D", "R", "T")
        return LieModel(
            robot.name, names, ("S", "D"), (2, 3), _car(robot), aliases, basis, (2, 3, 4)
        )
    if robot.kind == "snake" and robot.links >= 3:
        # The first five coordinates (x, y, theta, phi1, phi2) of the fields and their
        # brackets are the 3-link snake's (the first three wheels fix the body from
        # dphi1, dphi2), so the fields to depth 3 there have det = -det G* = -l^6/det B^4
        # ([[g1,g2],g2] = -h3): growth (2, 3, 5) exactly, for every N.
        depends = tuple(range(2, 3 + robot.n_joints))
        basis = ("g1", "g2", "[g1,g2]", "[g1,[g1,g2]]", "[[g1,g2],g2]")

        def clearance(q: np.ndarray) -> float:
            return abs(math.sin(q[3]) - math.sin(q[4]) + math.sin(q[3] - q[4]))

        return LieModel(
            robot.name,
            names,
            ("g1", "g2"),
            depends,
            _snake(robot),
            {},
            basis,
            (2, 3, 5),
            clearance,
        )
    raise LieError(
        f"{robot.name} has no field model here: jets cover snakes of 3 to 16 links and the car"
    )
