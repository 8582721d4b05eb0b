"""Pointwise kinematics through the C core: wheels, minimum-slip body velocity, the
control vector fields with their brackets, and the filtration's growth vector."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from snakebot.core import ffi, lib
from snakebot.model.kinematics.ccore import (
    FORMS,
    KinematicsError,
    UnsupportedModel,
    as_doubles,
    c_robot,
    check,
    dptr,
)
from snakebot.model.robots import Friction, Robot

#: Names of the fields in the thesis's order, and their brackets.
FIELD_NAMES = {
    "snake3": ("g1", "g2", "h1", "h2", "h3"),
    "trident": ("g1", "g2", "g3", "h1", "h2", "h3"),
}
BRACKETS = {
    "snake3": {"h1": ("g1", "g2"), "h2": ("g1", "h1"), "h3": ("g2", "h1")},
    "trident": {"h1": ("g1", "g2"), "h2": ("g1", "g3"), "h3": ("g2", "g3")},
}
#: Field names added at each step of the filtration.
FILTRATION = {
    "snake3": (("g1", "g2"), ("h1",), ("h2", "h3")),
    "trident": (("g1", "g2", "g3"), ("h1", "h2", "h3")),
}
#: Growth vector wherever det G* is non-zero (G*: all fields side by side is then
#: invertible, so every step of the filtration has full rank).
GENERIC_GROWTH = {"snake3": (2, 3, 5), "trident": (3, 6)}
#: Rank tolerance on unit-normalised columns, used only where det G* = 0 exactly
#: (a trident with r = 0); elsewhere the growth follows from det G*.
RANK_TOL = 1e-9


def field_model(robot: Robot) -> str:
    """``"snake3"`` or ``"trident"``: which field model the robot has (error otherwise)."""
    if robot.kind == "trident":
        return "trident"
    if robot.links == 3:
        return "snake3"
    what = f"a {robot.links}-link snake" if robot.kind == "snake" else f"a {robot.kind}"
    raise UnsupportedModel(
        f"{robot.name} is {what}: its two control fields and their brackets are in "
        f"`snakebot model fields {robot.name}`; field-driven integration and `gait field` "
        "cover the 3-link snake and the trident"
    )


def default_form(robot: Robot) -> str:
    """The trident's default is body-velocity inputs; the snake's inputs are its joints."""
    return "body" if robot.kind == "trident" else "joint"


def _c_form(robot: Robot, form: str | None) -> int:
    if robot.kind != "trident":
        if form not in (None, "joint"):
            raise KinematicsError(
                lib.KIN_EINVAL,
                f"{robot.name}'s inputs are its joint "
                "velocities: the body and world forms apply to the trident only",
            ).about("form")
        return lib.KIN_FORM_BODY
    form = form or "body"
    if form not in FORMS:
        raise KinematicsError(lib.KIN_EINVAL, f"unknown form {form!r}: use body or world")
    return FORMS[form]


def wheels(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Wheel positions and unit rolling directions at q, each of shape (wheels, 2)."""
    qa = as_doubles(q, 3 + robot.n_joints, "q")
    pos = np.empty((robot.n_wheels, 2))
    direction = np.empty((robot.n_wheels, 2))
    check(lib.kin_wheels(c_robot(robot), dptr(qa), dptr(pos), dptr(direction)))
    return pos, direction


def wheel_speeds(robot: Robot, q: np.ndarray, qdot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each wheel's (normal, tangential) speed for the state velocity qdot."""
    n = 3 + robot.n_joints
    qa, qd = as_doubles(q, n, "q"), as_doubles(qdot, n, "qdot")
    normal = np.empty(robot.n_wheels)
    tangent = np.empty(robot.n_wheels)
    check(lib.kin_wheel_speeds(c_robot(robot), dptr(qa), dptr(qd), dptr(normal), dptr(tangent)))
    return normal, tangent


@dataclass(frozen=True)
class BodyVelocity:
    """Quasi-static result: ``xi`` = (dx, dy, dtheta) in the world frame, each wheel's
    normal ``slip`` speed, and the sticking rows' reciprocal condition number ``rcond``."""

    xi: np.ndarray
    slip: np.ndarray
    rcond: float


def body_velocity(
    robot: Robot, q: np.ndarray, dphi: np.ndarray, friction: Friction | None = None
) -> BodyVelocity:
    """The quasi-static body velocity for joint velocities dphi at q: the one minimising
    the wheels' frictional power (docs/models.md)."""
    qa = as_doubles(q, 3 + robot.n_joints, "q")
    da = as_doubles(dphi, robot.n_joints, "dphi")
    xi = np.empty(3)
    slip = np.empty(robot.n_wheels)
    rcond = ffi.new("double *")
    code = lib.kin_body_velocity(
        c_robot(robot, friction), dptr(qa), dptr(da), dptr(xi), dptr(slip), rcond
    )
    if code != lib.KIN_OK:  # the message formats q: only when there is one
        check(code, f"{robot.name} at q = {np.array2string(qa, precision=4)}")
    return BodyVelocity(xi, slip, float(rcond[0]))


@dataclass(frozen=True)
class QuasiStatic:
    """The body velocity ``xi`` with the forces behind it: ``lateral`` and ``rolling``
    (N, per wheel) the friction forces across (along n) and along (along t) each wheel,
    ``torque`` each joint's torque driving the motion (N times the robot's length unit)."""

    xi: np.ndarray
    lateral: np.ndarray
    rolling: np.ndarray
    torque: np.ndarray


def quasi_static(
    robot: Robot, q: np.ndarray, dphi: np.ndarray, friction: Friction | None = None
) -> QuasiStatic:
    """``body_velocity`` with each wheel's friction forces and the joints' torques."""
    qa = as_doubles(q, 3 + robot.n_joints, "q")
    da = as_doubles(dphi, robot.n_joints, "dphi")
    xi = np.empty(3)
    force = np.empty(2 * robot.n_wheels)
    torque = np.empty(robot.n_joints)
    code = lib.kin_quasi_static(
        c_robot(robot, friction), dptr(qa), dptr(da), dptr(xi), dptr(force), dptr(torque)
    )
    if code != lib.KIN_OK:  # the message formats q: only when there is one
        check(code, f"{robot.name} at q = {np.array2string(qa, precision=4)}")
    return QuasiStatic(xi, force[0::2].copy(), force[1::2].copy(), torque)


@dataclass(frozen=True)
class Path:
    """Per state of a sampled motion: the joints' quasi-static ``torque`` (states x
    joints) and the wheels' positions ``pos`` and unit rolling directions ``dir``
    (states x wheels x 2)."""

    torque: np.ndarray
    pos: np.ndarray
    dir: np.ndarray


def quasi_static_path(robot: Robot, q: np.ndarray, dphi: np.ndarray) -> Path:
    """``quasi_static``'s torques and ``wheels`` at every row of ``q`` (states x (3 +
    joints)) with the joint velocities in the rows of ``dphi``, in one call to the core."""
    count = len(q)
    qa = as_doubles(q, count * (3 + robot.n_joints), "q")
    da = as_doubles(dphi, count * robot.n_joints, "dphi")
    torque = np.empty((count, robot.n_joints))
    pos = np.empty((count, robot.n_wheels, 2))
    direction = np.empty((count, robot.n_wheels, 2))
    failed = ffi.new("int32_t *")
    code = lib.kin_quasi_static_path(
        c_robot(robot),
        count,
        dptr(qa),
        dptr(da),
        dptr(torque),
        dptr(pos),
        dptr(direction),
        failed,
    )
    if code != lib.KIN_OK:  # the message formats q: only when there is one
        where = np.array2string(qa.reshape(count, -1)[failed[0]], precision=4)
        check(code, f"{robot.name} at q = {where}")
    return Path(torque, pos, direction)


def det_g_star(robot: Robot, det_b: float) -> float:
    """det G* (all fields side by side, in the thesis's order) in closed form.

    3-link snake: ``l^6 / det B^4`` with ``det B = l (sin p1 - sin p2 + sin(p1 - p2))``:
    never zero where the fields exist, so the growth vector is (2, 3, 5) everywhere off
    the singular set, however near it. Trident: ``3 sqrt(3) r^2 / (2 l^6)`` in both
    input forms, a constant. Both were found from and are checked against the fields the
    core computes (tests/model/test_kin_fields.py)."""
    if robot.kind == "trident":
        return 3.0 * math.sqrt(3.0) * robot.r**2 / (2.0 * robot.l**6)
    return robot.l**6 / det_b**4


def singular_reason(robot: Robot, q: np.ndarray) -> str:
    """Which part of the 3-link snake's singular set q is on: det B =
    4 l sin((p1 - p2)/2) cos(p1/2) cos(p2/2) vanishes where phi1 = phi2 (the axles meet in
    a point, or are parallel) and where a joint is at +-pi (a link folded back)."""
    p1, p2 = float(q[3]), float(q[4])
    factors = {
        "phi1 = phi2": abs(math.sin((p1 - p2) / 2)),
        "phi1 = +-pi (link 2 folded back onto link 1)": abs(math.cos(p1 / 2)),
        "phi2 = +-pi (link 3 folded back onto link 2)": abs(math.cos(p2 / 2)),
    }
    return min(factors, key=lambda k: factors[k])


@dataclass(frozen=True)
class FieldSet:
    """The fields at one q. ``values`` is None where the model is singular."""

    robot: str
    form: str
    q: np.ndarray
    names: tuple[str, ...]
    values: np.ndarray | None  # (fields, n)
    det_b: float  # det B for the 3-link snake (zero on its singular set); 1 for the trident
    singular: bool
    det_exact: float | None = None  # det G* in closed form (det_g_star); None if singular

    def __getitem__(self, name: str) -> np.ndarray:
        if self.values is None:
            raise KinematicsError(lib.KIN_ESINGULAR, f"the fields are undefined at q = {self.q}")
        return self.values[self.names.index(name)]

    @property
    def model(self) -> str:
        return "trident" if len(self.names) == 6 else "snake3"

    def _unit_columns(self) -> np.ndarray:
        # Near a singular set the brackets grow far faster than the fields (1/det^5
        # against 1/det): unit columns keep that scale out of rank and conditioning.
        assert self.values is not None
        norms = np.maximum(np.linalg.norm(self.values, axis=1), 1e-300)
        return (self.values / norms[:, None]).T

    @property
    def growth(self) -> tuple[int, ...] | None:
        """Rank of Delta_1, Delta_2, ... (the growth vector): exact from det G* != 0;
        a numeric rank only where det G* is exactly zero."""
        if self.values is None or self.det_exact is None:
            return None
        if self.det_exact != 0.0:
            return GENERIC_GROWTH[self.model]
        ranks, count = [], 0
        unit = self._unit_columns()
        for step in FILTRATION[self.model]:
            count += len(step)
            ranks.append(int(np.linalg.matrix_rank(unit[:, :count], tol=RANK_TOL)))
        return tuple(ranks)

    @property
    def det(self) -> float | None:
        """det G*: the determinant of all fields side by side (columns g..., h...), from
        its closed form (det_g_star), exact near the singular set where a numeric
        determinant of the fields is not."""
        return None if self.values is None else self.det_exact

    @property
    def condition(self) -> float | None:
        """2-norm condition number of G* with unit columns: how near q is to losing rank
        numerically (it grows as det B^-2 towards the 3-link snake's singular set)."""
        return None if self.values is None else float(np.linalg.cond(self._unit_columns()))


def fields(robot: Robot, q: np.ndarray, form: str | None = None) -> FieldSet:
    """All fields (g..., h...) at q, in the thesis's order."""
    model = field_model(robot)
    c_form = _c_form(robot, form)
    n = 3 + robot.n_joints
    qa = as_doubles(q, n, "q")
    names = FIELD_NAMES[model]
    out = np.empty((len(names), n))
    det = ffi.new("double *")
    code = lib.kin_fields(c_robot(robot), c_form, dptr(qa), dptr(out), det)
    form_name = form or default_form(robot)
    if code == lib.KIN_ESINGULAR:
        return FieldSet(robot.name, form_name, qa, names, None, float(det[0]), True)
    if code != lib.KIN_OK:  # the message formats q: only when there is one
        check(code, f"{robot.name} at q = {qa}")
    exact = det_g_star(robot, float(det[0]))
    return FieldSet(robot.name, form_name, qa, names, out, float(det[0]), False, exact)


def field_velocity(
    robot: Robot, q: np.ndarray, u: np.ndarray, form: str | None = None
) -> np.ndarray:
    """qdot = sum_i u_i g_i(q)."""
    field_model(robot)
    n = 3 + robot.n_joints
    m = 2 if robot.kind == "snake" else 3
    qa, ua = as_doubles(q, n, "q"), as_doubles(u, m, "u")
    qdot = np.empty(n)
    code = lib.kin_field_velocity(
        c_robot(robot), _c_form(robot, form), dptr(qa), dptr(ua), dptr(qdot)
    )
    if code != lib.KIN_OK:  # the message formats q: only when there is one
        check(code, f"{robot.name} at q = {qa}")
    return qdot
