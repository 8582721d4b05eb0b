"""A MuJoCo model (MJCF text) of a robot: its links with mass, passive wheels that spin
freely on their axles, a floor with friction, and a hinge for every servo.

The robot moves in the plane: its first link (snake) or base (trident) slides in x, y
and z and turns about z; every other degree of freedom is a joint of the chain, a
snake link's slide in z on its parent, or a wheel's spin. Leaving z free lets the weight
settle on the wheels, which is what the floor's friction pushes against; pitch and roll
are left out because the real robot's brackets keep its links level. A snake's links
each slide in z so that each wheel carries its own link (`Robot.wheel_loads_n`, the
loads the quasi-static model weighs its wheels by): on one z for the whole chain, how
the weight spreads over more wheels than that z can tell apart is left to the contact
solver's regularisation, which put 0.69 N on snake5's end wheels and 1.02 N on its
middle one against 0.88 N each (docs/models.md). Only wheels touch the floor, and
nothing touches anything else (the joint limits keep the links apart).

Frames follow the kinematic model (docs/models.md): a snake's reference point (x, y) is
the free end of link 1, link k runs 2 l along its heading, its wheel at its middle rolls
along the link; a trident's base centre is (x, y), arm i leaves the corner at angle
alpha_i, its wheel at the arm's end rolls along the arm. Lengths are the robot's units
times ``physics.unit_m``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from xml.etree import ElementTree as ET

from snakebot.model.robots import Friction, Physics, Robot, RobotError
from snakebot.sim.physics.actuator import ARMATURE_KG_M2, Actuator

TIMESTEP_S = 0.0025
"""MuJoCo's step: fine enough that halving it moves no figure a prediction reports
(distance, slide, work, electrical energy) by 2 % (docs/models.md, "The physics world's
time step"; tests/sim/test_physics_convergence.py)."""

CONTROL_PERIOD_S = 0.01
"""How often the world sets each servo's drive from its registers and reports the joint
back: between, MuJoCo runs the drive as a linear law (the AX-12's own loop is faster)."""

LINK_WIDTH_M = 0.035
"""Width and height of a link's box (an AX-12A is 32 mm wide): only its inertia counts."""

WHEEL_WIDTH_M = 0.01

ROOT_JOINTS = ("x", "y", "z", "theta")

ROLLING_MODELS = ("contact", "axle")
"""How the wheels' rolling resistance enters MuJoCo: "contact" (condim 6: the contact's
rolling friction, a length, C_rr times the wheel's radius, so the resisting torque is
C_rr N R; the axle's torque as the wheel hinge's frictionloss) or "axle" (condim 3 and
all of it, C_rr N R plus the axle's torque, as the hinge's frictionloss)."""

ROLLING_MODEL = "contact"
"""The default: tests/sim/test_physics_friction.py measures both against a rolling test."""

TORSIONAL_M = 0.0
"""The contact's torsional (spin) friction, a length: a thin tyre's contact patch is a
few millimetres long, so turning a wheel about the vertical costs far less than sliding
it; 0 (none) rather than a guess."""


@dataclass(frozen=True)
class Names:
    """The MJCF names the world looks up: servo joints in robot order, wheels, and the
    slides in z from the root down the chain (a link's height is their sum up to its
    own)."""

    joints: tuple[str, ...]
    wheels: tuple[str, ...]
    heights: tuple[str, ...]


def physics_of(robot: Robot) -> Physics:
    """The robot's ``[physics]`` table, or an error saying how to add one."""
    if robot.physics is None:
        where = robot.source or robot.name
        raise RobotError(
            f"{where}: key 'physics' is missing: the physics world needs a [physics] table "
            "with unit_m (metres per length unit; see the built-in robot files)"
        )
    return robot.physics


def _fmt(*values: float) -> str:
    return " ".join(f"{v:.9g}" for v in values)


def _box(parent: ET.Element, length: float, mass: float) -> None:
    """A link of ``length`` along the body's x axis, from its origin."""
    ET.SubElement(
        parent,
        "geom",
        type="box",
        pos=_fmt(length / 2, 0, LINK_WIDTH_M / 2),
        size=_fmt(length / 2, LINK_WIDTH_M / 2, LINK_WIDTH_M / 2),
        mass=_fmt(mass),
        contype="0",
        conaffinity="0",
        rgba="0.85 0.55 0.15 1",
    )


@dataclass(frozen=True)
class WheelFriction:
    """One wheel's friction in MuJoCo's terms: the contact's ``condim`` and
    ``friction`` triple (sliding, torsional, rolling) and the hinge's ``frictionloss``."""

    condim: int
    contact: tuple[float, float, float]
    axle_nm: float


def wheel_friction(robot: Robot, friction: Friction, load_n: float, model: str) -> WheelFriction:
    """The robot's ``[friction]`` for a wheel carrying ``load_n`` newtons."""
    radius = physics_of(robot).wheel_radius_m
    if model == "contact":
        return WheelFriction(
            6, (friction.lateral, TORSIONAL_M, friction.rolling * radius), friction.axle_nm
        )
    if model == "axle":
        return WheelFriction(
            3,
            (friction.lateral, TORSIONAL_M, 0.0),
            friction.axle_nm + friction.rolling * load_n * radius,
        )
    raise RobotError(f"unknown rolling model {model!r}: use one of {', '.join(ROLLING_MODELS)}")


def _wheel(parent: ET.Element, name: str, x: float, phys: Physics, friction: WheelFriction) -> None:
    """A wheel at ``x`` on the body's x axis, its axle along the body's y axis."""
    body = ET.SubElement(parent, "body", name=name, pos=_fmt(x, 0, 0))
    ET.SubElement(
        body,
        "joint",
        name=name,
        type="hinge",
        axis="0 1 0",
        frictionloss=_fmt(friction.axle_nm),
    )
    ET.SubElement(
        body,
        "geom",
        type="cylinder",
        size=_fmt(phys.wheel_radius_m, WHEEL_WIDTH_M / 2),
        zaxis="0 1 0",
        mass=_fmt(phys.wheel_mass_kg),
        contype="0",
        conaffinity="0",
        rgba="0.15 0.15 0.15 1",
    )
    # The floor touches a sphere of the wheel's radius: one contact point under the axle
    # (a flat cylinder gives two, at twice the cost), the same point a thin tyre touches
    # at, since the robot cannot roll sideways.
    ET.SubElement(
        body,
        "geom",
        type="sphere",
        size=_fmt(phys.wheel_radius_m),
        mass="0",
        contype="1",
        conaffinity="0",
        condim=str(friction.condim),
        friction=_fmt(*friction.contact),
        group="3",
    )


def _servo_joint(body: ET.Element, name: str, lo: float, hi: float, act: Actuator) -> None:
    ET.SubElement(
        body,
        "joint",
        name=name,
        type="hinge",
        axis="0 0 1",
        range=_fmt(lo, hi),
        limited="true",
        damping=_fmt(act.damping),
        armature=_fmt(ARMATURE_KG_M2),
    )


def build_mjcf(
    robot: Robot,
    *,
    timestep: float = TIMESTEP_S,
    friction: Friction | None = None,
    rolling_model: str = ROLLING_MODEL,
) -> tuple[str, Names]:
    """The MJCF of ``robot`` and the names of its servo joints and wheels. ``friction``
    overrides the robot's ``[friction]``; ``rolling_model`` is one of ROLLING_MODELS."""
    phys = physics_of(robot)
    friction = robot.friction if friction is None else friction
    if not friction.lateral > 0 or not math.isfinite(friction.lateral):
        raise RobotError(
            f"the friction coefficient must be a positive number, not {friction.lateral}"
        )
    loads = robot.wheel_loads_n()
    wheel = [wheel_friction(robot, friction, float(n), rolling_model) for n in loads]
    act = Actuator.for_model(robot.servo_model)
    unit = phys.unit_m
    root = ET.Element("mujoco", model=robot.name)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    ET.SubElement(
        root,
        "option",
        timestep=_fmt(timestep),
        integrator="implicitfast",
        cone="elliptic",
    )
    visual = ET.SubElement(root, "visual")
    ET.SubElement(visual, "global", offwidth="640", offheight="480")
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(
        world,
        "geom",
        name="floor",
        type="plane",
        size="0 0 1",
        contype="0",
        conaffinity="1",
        friction=_fmt(*wheel[0].contact),
        rgba="0.9 0.9 0.9 1",
    )
    ET.SubElement(world, "light", pos="0 0 3", dir="0 0 -1", directional="true")
    base = ET.SubElement(world, "body", name="base", pos=_fmt(0, 0, phys.wheel_radius_m))
    for name in ROOT_JOINTS:
        kind = "hinge" if name == "theta" else "slide"
        axis = {"x": "1 0 0", "y": "0 1 0"}.get(name, "0 0 1")
        ET.SubElement(base, "joint", name=name, type=kind, axis=axis)
    joints = tuple(j.name for j in robot.joints)
    wheels: list[str] = []
    heights = ["z"]
    if robot.kind == "snake":
        length = 2 * robot.l * unit
        body = base
        for k in range(robot.links):
            if k > 0:
                body = ET.SubElement(body, "body", name=f"link{k + 1}", pos=_fmt(length, 0, 0))
                j = robot.joints[k - 1]
                _servo_joint(body, j.name, j.min_rad, j.max_rad, act)
                heights.append(f"link{k + 1}_z")
                ET.SubElement(body, "joint", name=heights[-1], type="slide", axis="0 0 1")
            _box(body, length, phys.link_mass_kg)
            wheels.append(f"wheel{k + 1}")
            _wheel(body, wheels[-1], length / 2, phys, wheel[k])
    else:
        r, arm = robot.r * unit, robot.l * unit
        ET.SubElement(
            base,
            "geom",
            type="cylinder",
            size=_fmt(max(r, LINK_WIDTH_M), LINK_WIDTH_M / 2),
            pos=_fmt(0, 0, LINK_WIDTH_M / 2),
            mass=_fmt(phys.link_mass_kg),
            contype="0",
            conaffinity="0",
            rgba="0.3 0.5 0.8 1",
        )
        for i, (alpha, j) in enumerate(zip(robot.alphas, robot.joints, strict=True)):
            body = ET.SubElement(
                base,
                "body",
                name=f"arm{i + 1}",
                pos=_fmt(r * math.cos(alpha), r * math.sin(alpha), 0),
                euler=_fmt(0, 0, alpha),
            )
            _servo_joint(body, j.name, j.min_rad, j.max_rad, act)
            _box(body, arm, phys.link_mass_kg)
            wheels.append(f"wheel{i + 1}")
            _wheel(body, wheels[-1], arm, phys, wheel[i])
    # the servos' drive: force = gain * ctrl + bias0 + bias1 * q, within +-forcerange;
    # the world sets gain, bias and range from each servo's registers as they change
    actuators = ET.SubElement(root, "actuator")
    for name in joints:
        ET.SubElement(
            actuators,
            "general",
            name=name,
            joint=name,
            gaintype="fixed",
            biastype="affine",
            gainprm="0",
            biasprm="0 0 0",
            forcelimited="true",
            forcerange=_fmt(-act.stall_nm, act.stall_nm),
        )
    return ET.tostring(root, encoding="unicode"), Names(joints, tuple(wheels), tuple(heights))
