"""The robot live in Foxglove: a Foxglove WebSocket server (the ``foxglove-sdk`` package)
streaming what the robot does, on ROS 2's topic names and message shapes so a ROS 2
user's tools read them; the same channels go into an MCAP file when one is asked for.

Topics (JSON-encoded, each with its JSON schema):

- ``/joint_states``: ``sensor_msgs/JointState``-shaped: the servo joints' names, present
  angles (rad), speeds (rad/s) and efforts (N m: the load times the stall torque);
- ``/snakebot/servos``: per joint the goal and present angles (rad), the load (fraction
  of the stall torque, + counter-clockwise) and the servo's error flags;
- ``/snakebot/controller``: the controller's state, as the command that has it reports it;
- ``/tf``: ``foxglove.FrameTransforms``: ``odom`` -> ``base`` when the body's pose is known
  (the emulator's world; on a real robot the predicted pose), and each link's frame from
  the joint angles, so the 3-D panel draws the robot from ``/robot_description``;
- ``/robot_description``: the robot's URDF (``snakebot robot export``), once, latched.

Loopback only unless a host is given: ``parse_endpoint("8765")`` is 127.0.0.1:8765.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from snakebot.errors import InputError
from snakebot.extras import available, require
from snakebot.model.robots import Robot

LOOPBACK = "127.0.0.1"
ODOM, BASE = "odom", "base"


class FoxgloveOptionError(InputError):
    """A Foxglove endpoint that cannot be used."""


def parse_endpoint(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` as (host, port); the host is loopback unless given."""
    host, _, port_text = text.rpartition(":")
    try:
        port = int(port_text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535:
        raise FoxgloveOptionError(
            f"{text!r} is not [HOST:]PORT: give a port from 0 to 65535 (0: any free one), "
            "e.g. 8765 or 0.0.0.0:8765 to listen beyond this machine"
        )
    return (host.strip("[]") or LOOPBACK), port


@dataclass(frozen=True)
class JointSample:
    """The servo joints at one moment, in the robot's joint order: angles in radians,
    speeds in rad/s, load as a signed fraction of the stall torque, error flags as the
    servo reports them."""

    goal: Sequence[float]
    present: Sequence[float]
    velocity: Sequence[float]
    load: Sequence[float]
    errors: Sequence[int]


def _stamp(seconds: float) -> dict[str, int]:
    sec = math.floor(seconds)
    return {"sec": int(sec), "nanosec": int(round((seconds - sec) * 1e9)) % 1_000_000_000}


def _numbers(description: str) -> dict[str, Any]:
    return {"type": "array", "items": {"type": "number"}, "description": description}


TIME = {
    "type": "object",
    "properties": {"sec": {"type": "integer"}, "nanosec": {"type": "integer"}},
}
JOINT_STATE_SCHEMA = {
    "title": "sensor_msgs/JointState",
    "type": "object",
    "properties": {
        "header": {
            "type": "object",
            "properties": {"stamp": TIME, "frame_id": {"type": "string"}},
        },
        "name": {"type": "array", "items": {"type": "string"}},
        "position": _numbers("present angle, rad"),
        "velocity": _numbers("rad/s"),
        "effort": _numbers("N m"),
    },
}
SERVOS_SCHEMA = {
    "title": "snakebot/Servos",
    "type": "object",
    "properties": {
        "stamp": TIME,
        "name": {"type": "array", "items": {"type": "string"}},
        "goal": _numbers("goal angle, rad"),
        "present": _numbers("present angle, rad"),
        "load": _numbers("fraction of the stall torque, + counter-clockwise"),
        "error": {"type": "array", "items": {"type": "integer"}},
    },
}
VECTOR = {
    "type": "object",
    "properties": {k: {"type": "number"} for k in "xyz"},
}
QUATERNION = {
    "type": "object",
    "properties": {k: {"type": "number"} for k in "xyzw"},
}
TF_SCHEMA = {
    "title": "foxglove.FrameTransforms",
    "type": "object",
    "properties": {
        "transforms": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "timestamp": TIME,
                    "parent_frame_id": {"type": "string"},
                    "child_frame_id": {"type": "string"},
                    "translation": VECTOR,
                    "rotation": QUATERNION,
                },
            },
        }
    },
}
STRING_SCHEMA = {"title": "std_msgs/String", "type": "object", "properties": {"data": {}}}
CONTROLLER_SCHEMA = {"title": "snakebot/Controller", "type": "object"}

CHANNELS: dict[str, tuple[str, dict[str, Any]]] = {
    "/joint_states": ("sensor_msgs/msg/JointState", JOINT_STATE_SCHEMA),
    "/snakebot/servos": ("snakebot/Servos", SERVOS_SCHEMA),
    "/snakebot/controller": ("snakebot/Controller", CONTROLLER_SCHEMA),
    "/tf": ("foxglove.FrameTransforms", TF_SCHEMA),
    "/robot_description": ("std_msgs/msg/String", STRING_SCHEMA),
}
"""Topic -> (schema name, JSON schema)."""


def _yaw_quaternion(yaw: float) -> dict[str, float]:
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}


def _quaternion_of_rpy(rpy: Sequence[float]) -> tuple[float, float, float, float]:
    r, p, y = (a / 2 for a in rpy)
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def _times(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float, float]:
    """Hamilton product of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


@dataclass(frozen=True)
class _UrdfJoint:
    name: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rotation: tuple[float, float, float, float]
    axis_z: bool


def _urdf_joints(urdf: str) -> list[_UrdfJoint]:
    out = []
    for joint in ET.fromstring(urdf).iter("joint"):
        origin = joint.find("origin")
        attrs = origin.attrib if origin is not None else {}
        xyz = tuple(float(v) for v in attrs.get("xyz", "0 0 0").split())
        rpy = tuple(float(v) for v in attrs.get("rpy", "0 0 0").split())
        axis = joint.find("axis")
        out.append(
            _UrdfJoint(
                joint.get("name", ""),
                joint.find("parent").get("link", ""),  # type: ignore[union-attr]
                joint.find("child").get("link", ""),  # type: ignore[union-attr]
                xyz,  # type: ignore[arg-type]
                _quaternion_of_rpy(rpy),
                axis is not None and axis.get("xyz", "").split() == ["0", "0", "1"],
            )
        )
    return out


def robot_urdf(robot: Robot) -> str | None:
    """The robot's URDF for the 3-D panel, or None where it cannot be made (no MuJoCo,
    no [physics] table)."""
    if robot.physics is None or not available("mujoco"):
        return None
    from snakebot.sim.physics.export import export_urdf

    return export_urdf(robot)


class FoxgloveLive:
    """A Foxglove WebSocket server on ``host``:``port`` (0: any free port, see
    :attr:`port`) for ``robot``, and an MCAP file of the same channels if ``mcap`` is
    given."""

    def __init__(
        self, robot: Robot, host: str = LOOPBACK, port: int = 8765, *, mcap: Path | None = None
    ) -> None:
        require("foxglove", "the Foxglove bridge", params=("foxglove",))
        import foxglove

        self.robot = robot
        self._mcap = foxglove.open_mcap(str(mcap), allow_overwrite=True) if mcap else None
        try:
            self.server = foxglove.start_server(name=f"snakebot {robot.name}", host=host, port=port)
        except Exception as exc:
            if self._mcap is not None:
                self._mcap.close()
            raise FoxgloveOptionError(
                f"the Foxglove server cannot listen on {host}:{port} ({exc}): choose another "
                "port (port 0 takes any free one)"
            ).about("foxglove") from None
        self.channels = {
            topic: foxglove.Channel(
                topic,
                schema=foxglove.Schema(
                    name=name, encoding="jsonschema", data=json.dumps(schema).encode()
                ),
                message_encoding="json",
            )
            for topic, (name, schema) in CHANNELS.items()
        }
        self.stall_nm = _stall_torque(robot)
        self.urdf = robot_urdf(robot)
        self._joints = _urdf_joints(self.urdf) if self.urdf else []
        self._described = 0.0

    @property
    def port(self) -> int:
        return int(self.server.port)

    def publish(
        self,
        stamp_s: float,
        joints: JointSample,
        pose: Sequence[float] | None = None,
        controller: Mapping[str, Any] | None = None,
    ) -> None:
        """Send one moment: the joints, the body's ``pose`` (x, y in the robot's units,
        theta) if known, and the controller's state if given."""
        names = [j.name for j in self.robot.joints]
        stamp = _stamp(stamp_s)
        log_ns = time.time_ns()
        self.channels["/joint_states"].log(
            {
                "header": {"stamp": stamp, "frame_id": ""},
                "name": names,
                "position": [float(v) for v in joints.present],
                "velocity": [float(v) for v in joints.velocity],
                "effort": [float(v) * self.stall_nm for v in joints.load],
            },
            log_time=log_ns,
        )
        self.channels["/snakebot/servos"].log(
            {
                "stamp": stamp,
                "name": names,
                "goal": [float(v) for v in joints.goal],
                "present": [float(v) for v in joints.present],
                "load": [float(v) for v in joints.load],
                "error": [int(v) for v in joints.errors],
            },
            log_time=log_ns,
        )
        if controller is not None:
            self.channels["/snakebot/controller"].log(dict(controller), log_time=log_ns)
        self._tf(stamp, joints, pose, log_ns)
        if self.urdf is not None and (not self._described or stamp_s - self._described > 1.0):
            # sent again every second: a panel that joins later still gets the robot
            self.channels["/robot_description"].log({"data": self.urdf}, log_time=log_ns)
            self._described = stamp_s or 1e-9

    def _tf(
        self, stamp: dict[str, int], joints: JointSample, pose: Sequence[float] | None, ns: int
    ) -> None:
        transforms = []
        if pose is not None:
            unit = self.robot.physics.unit_m if self.robot.physics is not None else 1.0
            x, y, theta = (float(v) for v in pose)
            radius = self.robot.physics.wheel_radius_m if self.robot.physics is not None else 0.0
            transforms.append(
                {
                    "timestamp": stamp,
                    "parent_frame_id": ODOM,
                    "child_frame_id": BASE,
                    "translation": {"x": x * unit, "y": y * unit, "z": radius},
                    "rotation": _yaw_quaternion(theta),
                }
            )
        angles = {j.name: float(a) for j, a in zip(self.robot.joints, joints.present, strict=True)}
        for j in self._joints:
            turn = angles.get(j.name, 0.0) if j.axis_z else 0.0
            q = _times(j.rotation, (0.0, 0.0, math.sin(turn / 2), math.cos(turn / 2)))
            transforms.append(
                {
                    "timestamp": stamp,
                    "parent_frame_id": j.parent,
                    "child_frame_id": j.child,
                    "translation": dict(zip("xyz", j.xyz, strict=True)),
                    "rotation": dict(zip("xyzw", q, strict=True)),
                }
            )
        if transforms:
            self.channels["/tf"].log({"transforms": transforms}, log_time=ns)

    def close(self) -> None:
        self.server.stop()
        for channel in self.channels.values():
            channel.close()
        if self._mcap is not None:
            self._mcap.close()
            self._mcap = None


def _stall_torque(robot: Robot) -> float:
    """The servo model's stall torque (N m), which turns a load into an effort."""
    from snakebot.sim.servo import motor

    return float(motor.spec_for(robot.servo_model).stall_torque_nm)


def servo_sample(robot: Robot, servos: Sequence[Any]) -> JointSample:
    """The joints of ``robot`` from its emulated servos (in joint order), as they are."""
    from snakebot.model.robots import TICKS_PER_RAD

    goal, present, velocity, load, errors = [], [], [], [], []
    for joint, servo in zip(robot.joints, servos, strict=True):
        goal.append(joint.tick_to_angle(servo.regs.get("Goal Position")))
        present.append(joint.tick_to_angle(servo.pos))
        velocity.append(joint.sign * servo.vel / TICKS_PER_RAD)
        # the load register's direction bit: clockwise is toward fewer ticks
        ccw = -1.0 if servo.load_cw else 1.0
        load.append(joint.sign * ccw * servo.load_fraction)
        errors.append(int(servo.errors))
    return JointSample(goal, present, velocity, load, errors)


def publish_emulated(live: FoxgloveLive, emulated: Any) -> None:
    """One moment of an emulated robot (:class:`snakebot.sim.serve.EmulatedRobot`): its
    servos and its world's pose, stamped with world time."""
    robot = emulated.robot
    with emulated.lock:
        bus = emulated.bus
        servos = [bus.servo(j.servo_id) for j in robot.joints]
        for servo in servos:
            servo.advance(bus.now)
        sample = servo_sample(robot, servos)
        pose = [float(v) for v in emulated.world.pose]
        stamp = bus.now - emulated.world.start_time
    live.publish(stamp, sample, pose)
