"""Numeric kinematics through the C core (``snakebot._core``): wheel geometry, the
quasi-static body velocity (Coulomb friction), the control vector fields and their Lie brackets, and
whole-trajectory integrators (RK4, Dormand-Prince 5(4) and 8(5,3)), one trajectory or
a grid of schedules per call.

May import: as the ``model`` layer (``model.robots``, ``formats``, ``facts``, the
package root)."""

from __future__ import annotations

from snakebot.model.kinematics.ccore import KinematicsError, Options, SingularConfiguration
from snakebot.model.kinematics.integrate import (
    Batch,
    Inputs,
    Sines,
    Table,
    Trajectory,
    integrate_fields,
    integrate_joints,
    integrate_joints_batch,
    schedule_eval,
)
from snakebot.model.kinematics.model import (
    BRACKETS,
    FIELD_NAMES,
    BodyVelocity,
    FieldSet,
    Path,
    QuasiStatic,
    body_velocity,
    default_form,
    field_model,
    field_velocity,
    fields,
    quasi_static,
    quasi_static_path,
    wheel_speeds,
    wheels,
)

__all__ = [
    "BRACKETS",
    "Batch",
    "FIELD_NAMES",
    "BodyVelocity",
    "FieldSet",
    "Inputs",
    "KinematicsError",
    "Options",
    "Path",
    "QuasiStatic",
    "SingularConfiguration",
    "Sines",
    "Table",
    "Trajectory",
    "body_velocity",
    "default_form",
    "field_model",
    "field_velocity",
    "fields",
    "integrate_fields",
    "integrate_joints",
    "integrate_joints_batch",
    "quasi_static",
    "quasi_static_path",
    "schedule_eval",
    "wheel_speeds",
    "wheels",
]
