"""Pointwise kinematics through the C core: wheels, minimum-slip body velocity, the
control vector fields with their brackets, and the filtration's growth vector."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from snakebot.core import ffi, lib
from snakebot.kinematics.ccore import (
    FORMS,
    KinematicsError,
    as_doubles,
    c_robot,
    check,
    dptr,
)
from snakebot.robots import Robot

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
RANK_TOL = 1e-9


def field_model(robot: Robot) -> str:
    """``"snake3"`` or ``"trident"``: which field model the robot has (error otherwise)."""
    if robot.kind == "trident":
        return "trident"
    if robot.links == 3:
        return "snake3"
    raise KinematicsError(
        lib.KIN_EUNSUPPORTED,
        f"{robot.name} is a {robot.links}-link snake: with more than 3 wheels the non-slip "
        "constraints over-determine the body, so there are no control vector fields",
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
                "velocities: --form body|world applies to the trident only",
            )
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
    """Minimum-slip result: ``xi`` = (dx, dy, dtheta) in the world frame, each wheel's
    normal ``slip`` speed, and the problem's reciprocal condition number ``rcond``."""

    xi: np.ndarray
    slip: np.ndarray
    rcond: float


def body_velocity(
    robot: Robot, q: np.ndarray, dphi: np.ndarray, c_t: float | None = None
) -> BodyVelocity:
    """The minimum-slip body velocity for joint velocities dphi at q."""
    qa = as_doubles(q, 3 + robot.n_joints, "q")
    da = as_doubles(dphi, robot.n_joints, "dphi")
    xi = np.empty(3)
    slip = np.empty(robot.n_wheels)
    rcond = ffi.new("double *")
    code = lib.kin_body_velocity(
        c_robot(robot, c_t), dptr(qa), dptr(da), dptr(xi), dptr(slip), rcond
    )
    check(code, f"{robot.name} at q = {np.array2string(qa, precision=4)}")
    return BodyVelocity(xi, slip, float(rcond[0]))


@dataclass(frozen=True)
class FieldSet:
    """The fields at one q. ``values`` is None where the model is singular."""

    robot: str
    form: str
    q: np.ndarray
    names: tuple[str, ...]
    values: np.ndarray | None  # (fields, n)
    det_b: float  # det B for the 3-link snake (zero on its singular line); 1 for the trident
    singular: bool

    def __getitem__(self, name: str) -> np.ndarray:
        if self.values is None:
            raise KinematicsError(lib.KIN_ESINGULAR, f"the fields are undefined at q = {self.q}")
        return self.values[self.names.index(name)]

    @property
    def growth(self) -> tuple[int, ...] | None:
        """Rank of Delta_1, Delta_2, ... (the growth vector)."""
        if self.values is None:
            return None
        model = "trident" if len(self.names) == 6 else "snake3"
        ranks, cols = [], []
        for step in FILTRATION[model]:
            # Unit columns: near a singular set the brackets grow far faster than the
            # fields (1/det^5 against 1/det), which must not decide the rank.
            cols += [self[n] / max(np.linalg.norm(self[n]), 1e-300) for n in step]
            ranks.append(int(np.linalg.matrix_rank(np.array(cols), tol=RANK_TOL)))
        return tuple(ranks)

    @property
    def det(self) -> float | None:
        """det G*: the determinant of all fields side by side (columns g..., h...)."""
        return None if self.values is None else float(np.linalg.det(self.values.T))


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
    check(code, f"{robot.name} at q = {qa}")
    return FieldSet(robot.name, form_name, qa, names, out, float(det[0]), False)


def field_velocity(
    robot: Robot, q: np.ndarray, u: np.ndarray, form: str | None = None
) -> np.ndarray:
    """qdot = sum_i u_i g_i(q)."""
    field_model(robot)
    n = 3 + robot.n_joints
    m = 2 if robot.kind == "snake" else 3
    qa, ua = as_doubles(q, n, "q"), as_doubles(u, m, "u")
    qdot = np.empty(n)
    check(
        lib.kin_field_velocity(
            c_robot(robot), _c_form(robot, form), dptr(qa), dptr(ua), dptr(qdot)
        ),
        f"{robot.name} at q = {qa}",
    )
    return qdot
