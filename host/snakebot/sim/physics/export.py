"""The robot for other tools: the physics world's MJCF, and a URDF made from the same model.

Both come from :func:`snakebot.sim.physics.mjcf.build_mjcf`, so the masses, inertias,
joint limits and wheels are the ones the physics world simulates. The URDF is written
from the model MuJoCo compiles out of that MJCF (each body's mass, centre of mass and
principal inertia as MuJoCo works them out from its geoms), which keeps one source for
every number.

The URDF follows the ROS convention for a mobile robot: its root link ``base`` has no
joint to the world (the body's pose is the odometry, ``/tf`` odom -> base); each servo
is a ``revolute`` joint with its limits, the stall torque as its effort and the no-load
speed as its velocity; each wheel is a ``continuous`` joint with its rolling damping.
Links are drawn as boxes, wheels as cylinders; the only collision shape is a sphere of
the wheel's radius, the one contact the physics world gives a wheel. What URDF cannot
say is left out: the floor, the wheel-floor friction coefficient (``mu``, written as a
comment), the gear train's armature, and the servos' drive.

In the exported MJCF the servos' drive, which the physics world sets from the registers
as it runs, becomes a plain position servo (the AX-12's proportional band at its default
compliance slope), so a model loaded on its own holds its joints and follows ``ctrl``.
"""

from __future__ import annotations

import math
from xml.etree import ElementTree as ET

import numpy as np

from snakebot.extras import require
from snakebot.model.robots import TICKS_PER_RAD, Robot
from snakebot.sim.physics.actuator import ARMATURE_KG_M2, Actuator
from snakebot.sim.physics.mjcf import build_mjcf, physics_of

DEFAULT_SLOPE_TICKS = 32
"""The AX-12's default compliance slope: full duty 32 ticks from the goal."""


def position_gain(robot: Robot) -> float:
    """N m per radian of a position servo that reaches the stall torque at the default
    compliance slope."""
    return Actuator.for_model(robot.servo_model).stall_nm * TICKS_PER_RAD / DEFAULT_SLOPE_TICKS


def export_mjcf(robot: Robot) -> str:
    """The physics world's MJCF of ``robot``, its servos as position actuators."""
    xml, _ = build_mjcf(robot)
    root = ET.fromstring(xml)
    kp = position_gain(robot)
    for act in root.iter("general"):
        act.set("gainprm", f"{kp:.9g}")
        act.set("biasprm", f"0 {-kp:.9g} 0")
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def _fmt(values: np.ndarray | list[float]) -> str:
    return " ".join(f"{float(v):.9g}" for v in values)


def _rpy(quat: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (URDF's fixed-axis x-y-z) of a MuJoCo quaternion (w, x, y, z)."""
    w, x, y, z = (float(v) for v in quat)
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.array([roll, pitch, yaw])


def _origin(parent: ET.Element, pos: np.ndarray, quat: np.ndarray) -> None:
    ET.SubElement(parent, "origin", xyz=_fmt(pos), rpy=_fmt(_rpy(quat)))


def _shape(parent: ET.Element, kind: int, size: np.ndarray, mujoco: object) -> None:
    geom = ET.SubElement(parent, "geometry")
    types = mujoco.mjtGeom  # type: ignore[attr-defined]
    if kind == types.mjGEOM_BOX:
        ET.SubElement(geom, "box", size=_fmt(2 * size))
    elif kind == types.mjGEOM_CYLINDER:
        ET.SubElement(geom, "cylinder", radius=_fmt(size[:1]), length=_fmt([2 * size[1]]))
    else:
        ET.SubElement(geom, "sphere", radius=_fmt(size[:1]))


def export_urdf(robot: Robot) -> str:
    """A URDF of ``robot`` with the physics world's geometry, masses and joints."""
    require("mujoco", "the URDF export")
    import mujoco

    physics_of(robot)  # a robot without a body is refused here, with the fix
    act = Actuator.for_model(robot.servo_model)
    xml, names = build_mjcf(robot)
    m = mujoco.MjModel.from_xml_string(xml)
    root = ET.Element("robot", name=robot.name)
    root.append(
        ET.Comment(
            f" snakebot robot export of {robot.name}: wheel-floor friction mu = "
            f"{robot.friction.lateral:g}; "
            f"each servo joint's armature {ARMATURE_KG_M2:g} kg m^2 (not in URDF) "
        )
    )
    # MuJoCo's own URDF extension: keep the root link a body of its own, and the visuals
    ET.SubElement(
        ET.SubElement(root, "mujoco"), "compiler", fusestatic="false", discardvisual="false"
    )
    colors: dict[str, str] = {}
    servo_joints = set(names.joints)
    for b in range(1, m.nbody):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
        link = ET.SubElement(root, "link", name=name)
        inertial = ET.SubElement(link, "inertial")
        _origin(inertial, m.body_ipos[b], m.body_iquat[b])
        ET.SubElement(inertial, "mass", value=_fmt([m.body_mass[b]]))
        ixx, iyy, izz = m.body_inertia[b]
        ET.SubElement(
            inertial,
            "inertia",
            ixx=_fmt([ixx]),
            ixy="0",
            ixz="0",
            iyy=_fmt([iyy]),
            iyz="0",
            izz=_fmt([izz]),
        )
        for g in range(m.body_geomadr[b], m.body_geomadr[b] + m.body_geomnum[b]):
            touches = m.geom_contype[g] or m.geom_conaffinity[g]
            part = ET.SubElement(link, "collision" if touches else "visual")
            _origin(part, m.geom_pos[g], m.geom_quat[g])
            _shape(part, int(m.geom_type[g]), m.geom_size[g], mujoco)
            if not touches:
                rgba = _fmt(m.geom_rgba[g])
                colour = colors.setdefault(rgba, f"colour{len(colors) + 1}")
                ET.SubElement(ET.SubElement(part, "material", name=colour), "color", rgba=rgba)
        parent = int(m.body_parentid[b])
        if parent == 0:
            continue  # the root link: its pose is the odometry
        joints = range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])
        jname = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, joints[0]) if joints else None
        kind = "fixed" if jname is None else "revolute" if jname in servo_joints else "continuous"
        joint = ET.SubElement(root, "joint", name=jname or f"{name}_fixed", type=kind)
        _origin(joint, m.body_pos[b], m.body_quat[b])
        ET.SubElement(joint, "parent", link=mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, parent))
        ET.SubElement(joint, "child", link=name)
        if jname is None:
            continue
        j = joints[0]
        ET.SubElement(joint, "axis", xyz=_fmt(m.jnt_axis[j]))
        ET.SubElement(joint, "dynamics", damping=_fmt([m.dof_damping[m.jnt_dofadr[j]]]))
        if kind == "revolute":
            lo, hi = m.jnt_range[j]
            ET.SubElement(
                joint,
                "limit",
                lower=_fmt([lo]),
                upper=_fmt([hi]),
                effort=_fmt([act.stall_nm]),
                velocity=_fmt([act.no_load_rad_s]),
            )
    ET.indent(root)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
