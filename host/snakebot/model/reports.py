"""A robot's models as plain data (``snakebot model``): its description, and its control
vector fields and Lie brackets at a configuration, with the rank, the determinant and
the condition numbers that say how near the singular set it is."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from snakebot.model.gait.common import NEAR_SINGULAR_RCOND
from snakebot.model.kinematics import body_velocity, default_form, field_model, fields
from snakebot.model.kinematics.lie import lie_fields, lie_model
from snakebot.model.kinematics.model import singular_reason
from snakebot.model.robots import Robot


def describe_robot(rb: Robot) -> dict[str, Any]:
    """The robot description: geometry, friction, and each joint's servo (angles in deg)."""
    geometry = {
        "snake": lambda: {"links": rb.links, "half_link": rb.l},
        "car": lambda: {"wheelbase": rb.l},
        "trident": lambda: {
            "base_radius": rb.r,
            "arm_length": rb.l,
            "alphas_deg": [math.degrees(a) for a in rb.alphas],
        },
    }[rb.kind]()
    return {
        "robot": rb.name,
        "kind": rb.kind,
        "description": rb.description,
        "source": rb.source,
        "geometry": geometry,
        "friction": {
            "lateral": rb.friction.lateral,
            "rolling": rb.friction.rolling,
            "axle_nm": rb.friction.axle_nm,
            "wheel_loads_n": [float(v) for v in rb.wheel_loads_n()],
        },
        "servo": {"model": rb.servo_model, "max_speed_rad_s": rb.max_speed_rad_s},
        "joints": [
            {
                "name": j.name,
                "servo_id": j.servo_id,
                "zero_tick": j.zero_tick,
                "sign": j.sign,
                "min_deg": math.degrees(j.min_rad),
                "max_deg": math.degrees(j.max_rad),
                "ticks": list(j.tick_range),
            }
            for j in rb.joints
        ],
    }


def uses_lie_jets(rb: Robot, depth: int | None) -> bool:
    """Whether the fields come from the jets (any depth: snakes, the car) rather than
    the closed forms (the 3-link snake at the default depth, the trident)."""
    return rb.kind == "car" or (rb.kind == "snake" and (rb.links != 3 or depth is not None))


def joint_driven(rb: Robot, q: np.ndarray) -> dict[str, Any] | None:
    """How well the joints, driven as the servos drive them, determine the body at q
    by geometry alone: the reciprocal condition number of the wheels' no-slip rows, as
    the quasi-static model sees them with free rolling (None for the car). With rolling
    resistance the model is defined there too, but the motion then depends on friction."""
    if rb.kind not in ("snake", "trident"):
        return None
    free = replace(rb.friction, rolling=0.0, axle_nm=0.0)
    rcond = body_velocity(rb, q, np.zeros(rb.n_joints), free).rcond
    return {"rcond": rcond, "near_singular": rcond < NEAR_SINGULAR_RCOND}


def field_report(rb: Robot, at: list[float], form: str | None) -> dict[str, Any]:
    """The closed-form fields and brackets at ``at`` (snake3, trident) in ``form``: their
    values, growth vector, det G*, condition number and whether q is singular."""
    q = np.array(at)
    fs = fields(rb, q, form)
    data = {
        "robot": rb.name,
        "form": form or default_form(rb),
        "q": [float(v) for v in at],
        "fields": None
        if fs.values is None
        else {name: (fs[name] + 0.0).tolist() for name in fs.names},
        "growth": None if fs.growth is None else list(fs.growth),
        "det": fs.det,
        "condition": fs.condition,
        "singular": fs.singular,
        "joint_driven": joint_driven(rb, q),
    }
    if field_model(rb) == "snake3":
        data["det_b"] = fs.det_b
        if fs.singular:
            data["singular_where"] = singular_reason(rb, q)
    return data


def lie_report(rb: Robot, at: list[float], depth: int) -> dict[str, Any]:
    """The fields and a Lyndon basis of brackets to ``depth`` at ``at`` (snakes, the
    car), each named by its expression where it has an alias, with the growth vector
    (exact to ``growth_exact_to_depth``, numeric beyond) and the condition number."""
    lf = lie_fields(lie_model(rb), np.array(at), depth)
    inputs = "steering S, drive D" if rb.kind == "car" else "joint rates dphi1 (g1), dphi2 (g2)"
    data = {
        "robot": rb.name,
        "form": "car" if rb.kind == "car" else "joint",
        "q": [float(v) for v in lf.q],
        "coordinates": list(rb.state_names),
        "inputs": inputs,
        "depth": max(lf.depths),
        "fields": None
        if lf.values is None
        else {name: (lf[name] + 0.0).tolist() for name in lf.names},
        "depths": dict(zip(lf.names, lf.depths, strict=True)),
        "aliases": {v: k for k, v in lf.aliases.items()},
        "growth": None if lf.growth is None else list(lf.growth),
        "growth_exact_to_depth": len(lf.exact),
        "growth_reliable": lf.ranks_reliable,
        "condition": lf.condition,
        "singular": lf.singular,
        "joint_driven": joint_driven(rb, lf.q),
    }
    if lf.singular and rb.kind == "snake":
        data["singular_where"] = singular_reason(rb, lf.q)
    return data
