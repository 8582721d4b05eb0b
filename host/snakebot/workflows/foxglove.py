"""The robot live in Foxglove: a Foxglove WebSocket server (the ``foxglove-sdk`` package)
streaming the topics of :mod:`snakebot.formats.live_topics` (ROS 2's names and message
shapes, so a ROS 2 user's tools read them, and Foxglove's own typed ``SceneUpdate`` for
the bodies); the same channels go into an MCAP file when one is asked for.

The body's pose is the emulator's where there is one; on a real robot it is predicted
from the joint angles as they come (:class:`PosePredictor`, the kinematic model).

Loopback only unless a host is given: ``parse_endpoint("8765")`` is 127.0.0.1:8765.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Container, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

from snakebot.errors import InputError, quoted
from snakebot.extras import available, require
from snakebot.formats.live_topics import (
    CONTROLLER,
    JSON_CHANNELS,
    ROBOT_DESCRIPTION,
    SCENE,
    SDK_CHANNELS,
    TF,
    TOPICS,
    JointSample,
    Shape,
    body_transform,
    joint_messages,
    scene_message,
    stamp,
)
from snakebot.model.robots import Robot

LOOPBACK = "127.0.0.1"


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
            f"{quoted(text)} is not [HOST:]PORT: give a port from 0 to 65535 (0: any free one), "
            "e.g. 8765 or 0.0.0.0:8765 to listen beyond this machine"
        )
    return (host.strip("[]") or LOOPBACK), port


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


Message = tuple[str, Any]
"""A topic and one message on it: a JSON object, or on the topics of
:data:`~snakebot.formats.live_topics.SDK_CHANNELS` the ``foxglove-sdk``'s message."""


class LiveMessages:
    """The messages of the live topics, moment by moment, for ``robot`` (None: a
    controller whose robot is not named: no efforts, no links, no pose): what a
    :class:`FoxgloveLive` server sends and what an MCAP recording holds."""

    def __init__(self, robot: Robot | None) -> None:
        self.robot = robot
        self.stall_nm = _stall_torque(robot) if robot is not None else None
        self.urdf = robot_urdf(robot) if robot is not None else None
        self._joints = _urdf_joints(self.urdf) if self.urdf else []
        self._servo_joints = [j for j in self._joints if j.axis_z]
        self._described: float | None = None

    def moment(
        self,
        stamp_s: float,
        joints: JointSample,
        pose: Sequence[float] | None = None,
        controller: Mapping[str, Any] | None = None,
        scene: Sequence[Shape] | None = None,
        topics: Container[str] = TOPICS,
    ) -> list[Message]:
        """One moment on ``topics`` (default: all): the joints, the body's ``pose`` (x, y
        in the robot's units, theta) if known, the controller's state; the first time and
        every second after (a panel that joins later still gets them), what does not
        change: the robot's URDF, the bodies' ``scene`` (in the links' frames) if given,
        and the links' fixed frames (the wheels' axles; the servo joints' frames go out
        every time)."""
        due = self._described is None or abs(stamp_s - self._described) > 1.0
        out: list[Message] = [
            (topic, message)
            for topic, message in joint_messages(stamp_s, joints, self.stall_nm).items()
            if topic in topics
        ]
        if controller is not None and CONTROLLER in topics:
            out.append((CONTROLLER, dict(controller)))
        transforms = self._transforms(stamp_s, joints, pose, due) if TF in topics else None
        if transforms:
            out.append((TF, {"transforms": transforms}))
        if scene and SCENE in topics and due:
            out.append((SCENE, scene_message(stamp_s, scene)))
        if self.urdf is not None and ROBOT_DESCRIPTION in topics and due:
            out.append((ROBOT_DESCRIPTION, {"data": self.urdf}))
        if due and {TF, ROBOT_DESCRIPTION, SCENE} & set(topics):
            self._described = stamp_s
        return out

    def _transforms(
        self, stamp_s: float, joints: JointSample, pose: Sequence[float] | None, fixed: bool
    ) -> list[dict[str, Any]]:
        transforms = []
        physics = self.robot.physics if self.robot is not None else None
        if pose is not None:
            unit = physics.unit_m if physics is not None else 1.0
            x, y, theta = (float(v) for v in pose)
            radius = physics.wheel_radius_m if physics is not None else 0.0
            transforms.append(body_transform(stamp_s, x * unit, y * unit, radius, theta))
        angles = {n: float(a) for n, a in zip(joints.names, joints.present, strict=True)}
        when = stamp(stamp_s)
        for j in self._joints if fixed else self._servo_joints:
            turn = angles.get(j.name, 0.0) if j.axis_z else 0.0
            q = _times(j.rotation, (0.0, 0.0, math.sin(turn / 2), math.cos(turn / 2)))
            transforms.append(
                {
                    "timestamp": when,
                    "parent_frame_id": j.parent,
                    "child_frame_id": j.child,
                    "translation": dict(zip("xyz", j.xyz, strict=True)),
                    "rotation": dict(zip("xyzw", q, strict=True)),
                }
            )
        return transforms


DRAIN_S = 0.25
"""How long the server keeps going after the last message it was given before it stops:
time for its send queues to reach the clients on this machine or the local network."""


class FoxgloveLive:
    """A Foxglove WebSocket server on ``host``:``port`` (0: any free port, see
    :attr:`port`) sending :class:`LiveMessages` of ``robot``, and an MCAP file of the
    same channels if ``mcap`` is given (``messages``: a builder the caller shares, e.g.
    with its own recording)."""

    def __init__(
        self,
        robot: Robot | None,
        host: str = LOOPBACK,
        port: int = 8765,
        *,
        mcap: Path | None = None,
        name: str = "snakebot",
        messages: LiveMessages | None = None,
    ) -> None:
        require("foxglove", "the Foxglove server", extra="live", params=("foxglove",))
        import foxglove
        import foxglove.channels

        self.messages = messages if messages is not None else LiveMessages(robot)
        self._last_sent: float | None = None
        self._mcap = foxglove.open_mcap(str(mcap), allow_overwrite=True) if mcap else None
        title = f"snakebot {robot.name}" if robot is not None else name
        try:
            self.server = foxglove.start_server(name=title, host=host, port=port)
        except Exception as exc:
            if self._mcap is not None:
                self._mcap.close()
            raise FoxgloveOptionError(
                f"the Foxglove server cannot listen on {host}:{port} ({exc}): choose another "
                "port (0 takes any free one)"
            ).about("foxglove") from None
        self.channels: dict[str, Any] = {
            topic: foxglove.Channel(
                topic,
                schema=foxglove.Schema(
                    name=schema_name, encoding="jsonschema", data=json.dumps(schema).encode()
                ),
                message_encoding="json",
            )
            for topic, (schema_name, schema) in JSON_CHANNELS.items()
        }
        # Foxglove's own messages on the SDK's typed channels: its schema, not a copy
        for topic, message in SDK_CHANNELS.items():
            self.channels[topic] = getattr(foxglove.channels, f"{message}Channel")(topic)

    @property
    def port(self) -> int:
        return int(self.server.port)

    @property
    def stall_nm(self) -> float | None:
        return self.messages.stall_nm

    def watched(self) -> set[str]:
        """The topics someone takes now (a client subscribed, the MCAP file): the only
        ones worth building messages for."""
        return {topic for topic, channel in self.channels.items() if channel.has_sinks()}

    def publish(self, *moment: Any, **parts: Any) -> None:
        """Send one moment on the topics someone takes: the arguments of
        :meth:`LiveMessages.moment`."""
        topics = self.watched()
        if topics:
            self.send(self.messages.moment(*moment, **parts, topics=topics))

    def send(self, messages: Sequence[Message]) -> None:
        """Send messages built already, stamped now (each only if someone takes its topic:
        no encoding for no one)."""
        log_ns = time.time_ns()
        for topic, message in messages:
            channel = self.channels[topic]
            if channel.has_sinks():
                channel.log(message, log_time=log_ns)
                self._last_sent = time.monotonic()

    def close(self) -> None:
        """Stop the server once what was last sent had time to reach its clients (the
        server drops what it has not sent yet when it stops, and has no flush)."""
        if self._last_sent is not None:
            time.sleep(max(0.0, self._last_sent + DRAIN_S - time.monotonic()))
        self.server.stop()
        for channel in self.channels.values():
            channel.close()
        if self._mcap is not None:
            self._mcap.close()
            self._mcap = None

    def __enter__(self) -> FoxgloveLive:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class PosePredictor:
    """The body's pose of ``robot`` predicted from its joint angles as they come (the
    kinematic model, the joints taken as moving linearly between two updates): what
    ``/tf`` shows of a real robot. A stretch the model cannot integrate (a singular
    configuration) leaves the pose where it was."""

    def __init__(self, robot: Robot, pose: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        self.robot = robot
        self.pose = np.array(pose, dtype=float)
        self._last: tuple[float, np.ndarray] | None = None

    def update(self, t: float, angles: Sequence[float]) -> np.ndarray:
        """The pose (x, y in the robot's units, theta) at ``t`` seconds, the joints at
        ``angles`` (rad) then."""
        from snakebot.model.gait.common import PREDICT_OPTIONS
        from snakebot.model.kinematics import KinematicsError
        from snakebot.sim.world import integrate_samples

        now = np.array(angles, dtype=float)
        if self._last is not None and t > self._last[0]:
            before_t, before = self._last
            try:
                q, _ = integrate_samples(
                    self.robot,
                    np.vstack([before, now]),
                    t - before_t,
                    self.pose,
                    self.robot.friction,
                    PREDICT_OPTIONS,
                )
                self.pose = q[-1, :3].copy()
            except KinematicsError:
                pass  # a stretch the model cannot follow: the pose holds
        self._last = (t, now)
        return self.pose.copy()


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
    names = [j.name for j in robot.joints]
    return JointSample(names, goal, present, velocity, load, errors)


POSE_EVERY = 5
"""An emulated body's pose goes out every this many moments (10 a second at 50): the
kinematic world integrates its samples in batches, and asking for the pose at every
moment would make it integrate two at a time, at several times the cost."""


class EmulatedStream:
    """``sim serve`` live: each moment of an emulated robot
    (:class:`snakebot.sim.serve.EmulatedRobot`), stamped with world time: its servos, its
    world's pose every :data:`POSE_EVERY` moments, and in a physics world its bodies;
    nothing is read while no one watches."""

    def __init__(self, live: FoxgloveLive, emulated: Any) -> None:
        self.live, self.emulated = live, emulated
        self._moments = 0

    def tick(self) -> None:
        live, emulated = self.live, self.emulated
        watched = live.watched()
        if not watched:
            return
        robot = emulated.robot
        with_pose = self._moments % POSE_EVERY == 0 and TF in watched
        self._moments += 1
        with emulated.lock:
            bus = emulated.bus
            servos = [bus.servo(j.servo_id) for j in robot.joints]
            for servo in servos:
                servo.advance(bus.now)
            sample = servo_sample(robot, servos)
            world = emulated.world
            pose = [float(v) for v in world.pose] if with_pose else None
            stamp_s = bus.now - world.start_time
            scene = getattr(world, "shapes", None) if SCENE in watched else None
        live.send(live.messages.moment(stamp_s, sample, pose, scene=scene, topics=watched))


class SampleStream:
    """The live topics of the controller's telemetry, sample by sample
    (:class:`snakebot.link.controller.monitor.Sample`): to a Foxglove server once
    :meth:`serve` starts one, into a recording if one is given to :meth:`send`; with a
    ``robot`` (a name or file), the pose predicted from the joint angles."""

    def __init__(self, robot: str | None) -> None:
        from snakebot.model.robots import load_robot

        self.robot = load_robot(robot) if robot else None
        self.messages = LiveMessages(self.robot)
        self.predictor = PosePredictor(self.robot) if self.robot is not None else None
        self.server: FoxgloveLive | None = None

    def serve(self, host: str, port: int, name: str) -> FoxgloveLive:
        """Start the Foxglove server (the caller closes it)."""
        self.server = FoxgloveLive(self.robot, host, port, name=name, messages=self.messages)
        return self.server

    def send(self, s: Any, recording: Any = None) -> None:
        """One sample to the server and to ``recording`` (a
        :class:`snakebot.link.controller.mcap_log.McapLog`), if any."""
        from snakebot.link.controller.monitor import joint_sample

        joints = joint_sample(s)
        pose = None
        if self.predictor is not None and len(joints.present) == self.predictor.robot.n_joints:
            pose = self.predictor.update(s.t, joints.present)
        messages = self.messages.moment(s.t, joints, pose, s.controller_record())
        if self.server is not None:
            self.server.send(messages)
        if recording is not None:
            for topic, message in messages:
                recording.log(topic, message)


class BusStream:
    """``snakebot bus play`` live: every ``every`` control ticks, one look at each servo
    of ``robot`` over the bus (goal, present position, speed, load, errors), the pose
    predicted from the present angles, and the player's state, to a Foxglove server."""

    def __init__(self, robot: Robot, server: FoxgloveLive, every: int) -> None:
        self.robot = robot
        self.server = server
        self.every = max(1, every)
        self.predictor = PosePredictor(robot)

    def tick(self, client: Any, n: int, tick_s: float, player: Mapping[str, Any]) -> None:
        """After control tick ``n`` (``tick_s`` seconds each); ``player``: its state."""
        if n % self.every:
            return
        from snakebot.link.bus.play import look

        robot, stamp_s = self.robot, n * tick_s
        looks = look(client, robot.servo_ids)
        joints = JointSample(
            [j.name for j in robot.joints],
            [j.tick_to_angle(s.goal) for j, s in zip(robot.joints, looks, strict=True)],
            [j.tick_to_angle(s.position) for j, s in zip(robot.joints, looks, strict=True)],
            [j.sign * s.speed_rad_s for j, s in zip(robot.joints, looks, strict=True)],
            [j.sign * s.load for j, s in zip(robot.joints, looks, strict=True)],
            [s.error for s in looks],
        )
        pose = self.predictor.update(stamp_s, joints.present)
        self.server.publish(stamp_s, joints, pose, {"tick": n, **player})
