"""The robot's live topics: what a Foxglove WebSocket server streams and what an MCAP
recording holds, on ROS 2's topic names and message shapes, each named and described once
here (``snakebot.workflows.foxglove`` serves them, ``snakebot monitor --mcap`` records
them, ``snakebot foxglove-layout`` lays them out).

- ``/joint_states``: ``sensor_msgs/JointState``-shaped: the joints' names, present
  angles (rad), speeds (rad/s) and efforts (N m: the load times the stall torque; empty
  when the servo model is not known);
- ``/snakebot/servos``: per joint the goal and present angles (rad), the load (fraction
  of the stall torque, + counter-clockwise) and the servo's error flags;
- ``/snakebot/controller``: the controller's state, as the command that has it reports it;
- ``/tf``: ``foxglove.FrameTransforms``: ``odom`` -> ``base`` when the body's pose is known
  (the emulator's world; on a real robot the pose predicted from the joint angles), and
  each link's frame from the joint angles, so the 3-D panel draws the robot from
  ``/robot_description``;
- ``/robot_description``: the robot's URDF (``snakebot robot export``);
- ``/scene``: ``foxglove.SceneUpdate``: the robot's bodies as boxes, cylinders and spheres,
  each locked to its link's frame (so ``/tf`` moves them), where a physics world has them;
  sent once a second, as the bodies do not change.

Every topic but ``/scene`` is JSON, described by its JSON schema below
(:data:`JSON_CHANNELS`). ``/scene`` is Foxglove's own message, the ``foxglove-sdk``'s
typed ``SceneUpdate`` (:data:`SDK_CHANNELS`): its schema (protobuf) is the SDK's, not a
copy of ours, so the 3-D panel gets exactly what it reads. The helpers below build the
messages from plain numbers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from foxglove.messages import SceneUpdate

ODOM, BASE = "odom", "base"
"""The fixed frame and the body's frame."""

JOINT_STATES = "/joint_states"
SERVOS = "/snakebot/servos"
CONTROLLER = "/snakebot/controller"
TF = "/tf"
ROBOT_DESCRIPTION = "/robot_description"
SCENE = "/scene"


def _numbers(description: str) -> dict[str, Any]:
    return {"type": "array", "items": {"type": "number"}, "description": description}


def _object(**properties: Any) -> dict[str, Any]:
    return {"type": "object", "properties": properties}


TIME = _object(sec={"type": "integer"}, nanosec={"type": "integer"})
VECTOR = _object(**{k: {"type": "number"} for k in "xyz"})
QUATERNION = _object(**{k: {"type": "number"} for k in "xyzw"})

JOINT_STATE_SCHEMA = {
    "title": "sensor_msgs/JointState",
    **_object(
        header=_object(stamp=TIME, frame_id={"type": "string"}),
        name={"type": "array", "items": {"type": "string"}},
        position=_numbers("present angle, rad"),
        velocity=_numbers("rad/s"),
        effort=_numbers("N m"),
    ),
}
SERVOS_SCHEMA = {
    "title": "snakebot/Servos",
    **_object(
        stamp=TIME,
        name={"type": "array", "items": {"type": "string"}},
        goal=_numbers("goal angle, rad"),
        present=_numbers("present angle, rad"),
        load=_numbers("fraction of the stall torque, + counter-clockwise"),
        error={"type": "array", "items": {"type": "integer"}},
    ),
}
TRANSFORM = _object(
    timestamp=TIME,
    parent_frame_id={"type": "string"},
    child_frame_id={"type": "string"},
    translation=VECTOR,
    rotation=QUATERNION,
)
TF_SCHEMA = {
    "title": "foxglove.FrameTransforms",
    **_object(transforms={"type": "array", "items": TRANSFORM}),
}
STRING_SCHEMA = {"title": "std_msgs/String", **_object(data={"type": "string"})}
CONTROLLER_SCHEMA = {"title": "snakebot/Controller", "type": "object"}


JSON_CHANNELS: dict[str, tuple[str, dict[str, Any]]] = {
    JOINT_STATES: ("sensor_msgs/msg/JointState", JOINT_STATE_SCHEMA),
    SERVOS: ("snakebot/Servos", SERVOS_SCHEMA),
    CONTROLLER: ("snakebot/Controller", CONTROLLER_SCHEMA),
    TF: ("foxglove.FrameTransforms", TF_SCHEMA),
    ROBOT_DESCRIPTION: ("std_msgs/msg/String", STRING_SCHEMA),
}
"""The JSON topics: topic -> (schema name, JSON schema), served and recorded alike."""

SDK_CHANNELS: dict[str, str] = {SCENE: "SceneUpdate"}
"""The topics of Foxglove's own messages: topic -> the message's name in the
``foxglove-sdk`` (``foxglove.messages.<name>``, sent on ``foxglove.channels.<name>Channel``,
which carries the SDK's schema and encoding)."""

TOPICS: tuple[str, ...] = (*JSON_CHANNELS, *SDK_CHANNELS)
"""Every live topic."""


@dataclass(frozen=True)
class JointSample:
    """The joints at one moment, in the robot's joint order: their ``names``, angles in
    radians, speeds in rad/s, load as a signed fraction of the stall torque (+
    counter-clockwise), error flags as the servo reports them."""

    names: Sequence[str]
    goal: Sequence[float]
    present: Sequence[float]
    velocity: Sequence[float]
    load: Sequence[float]
    errors: Sequence[int]


def stamp(seconds: float) -> dict[str, int]:
    """``seconds`` as a ROS 2 time (sec, nanosec)."""
    sec = math.floor(seconds)
    return {"sec": int(sec), "nanosec": int(round((seconds - sec) * 1e9)) % 1_000_000_000}


def _floats(values: Sequence[float]) -> list[float]:
    return [float(v) for v in values]


def joint_messages(
    seconds: float, joints: JointSample, stall_nm: float | None
) -> dict[str, dict[str, Any]]:
    """The ``/joint_states`` and ``/snakebot/servos`` messages of one moment; efforts
    only when the servos' stall torque ``stall_nm`` is known."""
    when = stamp(seconds)
    names = list(joints.names)
    present = _floats(joints.present)
    effort = [] if stall_nm is None else [float(v) * stall_nm for v in joints.load]
    return {
        JOINT_STATES: {
            "header": {"stamp": when, "frame_id": ""},
            "name": names,
            "position": present,
            "velocity": _floats(joints.velocity),
            "effort": effort,
        },
        SERVOS: {
            "stamp": when,
            "name": names,
            "goal": _floats(joints.goal),
            "present": present,
            "load": _floats(joints.load),
            "error": [int(v) for v in joints.errors],
        },
    }


def yaw_quaternion(yaw: float) -> dict[str, float]:
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}


def body_transform(seconds: float, x_m: float, y_m: float, z_m: float, theta: float) -> dict:
    """``odom`` -> ``base``: the body at (x, y, z) metres, heading ``theta`` (rad)."""
    return {
        "timestamp": stamp(seconds),
        "parent_frame_id": ODOM,
        "child_frame_id": BASE,
        "translation": {"x": x_m, "y": y_m, "z": z_m},
        "rotation": yaw_quaternion(theta),
    }


@dataclass(frozen=True)
class Shape:
    """One body's shape for the 3-D scene: ``kind`` "cube", "cylinder" or "sphere", its
    full size along x, y, z (metres), its centre and orientation (quaternion x, y, z, w)
    in ``frame`` (a link's frame on ``/tf``: the shape moves with it)."""

    kind: str
    size: tuple[float, float, float]
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]
    frame: str = ODOM


ROBOT_COLOR = (0.2, 0.45, 0.85, 1.0)
"""The bodies' colour: red, green, blue, alpha."""


def scene_message(seconds: float, shapes: Sequence[Shape], entity: str = "robot") -> SceneUpdate:
    """The ``foxglove-sdk``'s ``SceneUpdate`` of ``shapes``: one entity ``entity/FRAME``
    per frame, locked to that frame (the transforms on ``/tf`` carry it), replacing the
    last (it needs the ``foxglove-sdk`` package, as the server that sends it does)."""
    from foxglove.messages import (
        Color,
        CubePrimitive,
        CylinderPrimitive,
        Pose,
        Quaternion,
        SceneEntity,
        SceneUpdate,
        SpherePrimitive,
        Timestamp,
        Vector3,
    )

    primitives: dict[str, tuple[str, Any]] = {
        "cube": ("cubes", CubePrimitive),
        "sphere": ("spheres", SpherePrimitive),
        # a straight cylinder: the same scale at both ends
        "cylinder": ("cylinders", partial(CylinderPrimitive, bottom_scale=1.0, top_scale=1.0)),
    }
    color = Color(**dict(zip("rgba", ROBOT_COLOR, strict=True)))
    frames: dict[str, dict[str, list[Any]]] = {}
    for s in shapes:
        group, primitive = primitives[s.kind]
        pose = Pose(
            position=Vector3(**dict(zip("xyz", s.position, strict=True))),
            orientation=Quaternion(**dict(zip("xyzw", s.orientation, strict=True))),
        )
        size = Vector3(**dict(zip("xyz", s.size, strict=True)))
        groups = frames.setdefault(s.frame, {g: [] for g, _ in primitives.values()})
        groups[group].append(primitive(pose=pose, size=size, color=color))
    when = stamp(seconds)
    return SceneUpdate(
        entities=[
            SceneEntity(
                timestamp=Timestamp(when["sec"], when["nanosec"]),
                frame_id=frame,
                id=f"{entity}/{frame}",
                frame_locked=True,
                **groups,
            )
            for frame, groups in frames.items()
        ]
    )


LAYOUT = "foxglove_layout.json"
"""The Foxglove layout for these topics, shipped with the package: the robot in a 3-D
panel (its URDF from ``/robot_description`` on the grid of ``odom``, following ``base``,
and ``/scene``), plots of the joints' present angles and goals, the controller's state
over time and the servos' latest message."""


def layout_text() -> str:
    """The layout's JSON, as shipped."""
    from importlib.resources import files

    return files(__package__).joinpath(LAYOUT).read_text(encoding="utf-8")
