"""The physics world's bodies as a 3-D scene (Foxglove's /scene on `sim serve --world
mujoco`): real MuJoCo; each geom in its link's frame, which the live /tf (the world's pose
and the joint angles through the exported URDF) carries to where MuJoCo has it; the scene
is the foxglove-sdk's own SceneUpdate, read back through its protobuf schema."""

from __future__ import annotations

import math

import pytest
from foxglove_client import in_frame, protobuf_class

from snakebot.facts import devices
from snakebot.formats.live_topics import ODOM, JointSample, scene_message
from snakebot.link.transport import DxlClient
from snakebot.model.robots import load_robot
from snakebot.sim.physics import PhysicsWorld
from snakebot.workflows.foxglove import LiveMessages
from snakebot.workflows.predict import sim_url

pytest.importorskip("mujoco")
pytest.importorskip("foxglove")
pytest.importorskip("google.protobuf")
SNAKE5 = load_robot("snake5")
GOAL_POSITION = devices.ax12().register("Goal Position").address
BENT = [0.4, -0.3, 0.2, -0.5]  # rad, joint by joint


def test_the_scene_rides_the_transforms_to_where_mujoco_has_the_bodies():
    client = DxlClient(sim_url(SNAKE5, True), echo=False)  # ideal servos: at their goals
    try:
        for joint, angle in zip(SNAKE5.joints, BENT, strict=True):
            client.write_u16(joint.servo_id, GOAL_POSITION, joint.angle_to_tick(angle))
        bus = client.port.bus
        bus.run_until(bus.now + 0.1)
        world = PhysicsWorld(bus, SNAKE5, pose=(1.0, 0.5, math.pi / 2))
        angles = [j.tick_to_angle(bus.servo(j.servo_id).pos) for j in SNAKE5.joints]
        shapes = world.shapes
        where = {g: world.data.geom_xpos[g].copy() for g in range(world.model.ngeom)}
        pose = world.pose
    finally:
        client.close()
    assert angles == pytest.approx(BENT, abs=0.01)
    names = [j.name for j in SNAKE5.joints]
    joints = JointSample(names, angles, angles, [0.0] * 4, [0.0] * 4, [0] * 4)
    messages = dict(LiveMessages(SNAKE5).moment(2.5, joints, pose, scene=shapes))
    frames = {t["child_frame_id"]: t for t in messages["/tf"]["transforms"]}
    drawn = [in_frame(frames, s.frame, s.position, ODOM) for s in shapes]
    # every geom MuJoCo has (but the floor), once, where MuJoCo has it (to the base's
    # height, which /tf takes as the wheel radius)
    robot_geoms = [p for g, p in where.items() if world.model.geom_bodyid[g] != 0]
    assert len(drawn) == len(robot_geoms) == 3 * SNAKE5.n_wheels
    for point, geom in zip(drawn, robot_geoms, strict=True):
        assert point == pytest.approx(geom, abs=2e-3)
    links = [s for s in shapes if s.kind == "cube"]
    assert [s.frame for s in links] == ["base", "link2", "link3", "link4", "link5"]
    assert links[0].size[0] == pytest.approx(2 * SNAKE5.l * SNAKE5.physics.unit_m)

    sent = messages["/scene"]
    schema = sent.get_schema()
    assert (schema.name, schema.encoding) == ("foxglove.SceneUpdate", "protobuf")
    scene = protobuf_class(schema.name, schema.data).FromString(sent.encode())
    assert [e.frame_id for e in scene.entities] == list(dict.fromkeys(s.frame for s in shapes))
    assert all(e.frame_locked and e.id == f"robot/{e.frame_id}" for e in scene.entities)
    assert all((e.timestamp.seconds, e.timestamp.nanos) == (2, 500_000_000) for e in scene.entities)

    def xyz(v):
        return (v.x, v.y, v.z)

    primitives = sorted(
        (
            e.frame_id,
            kind,
            xyz(p.size),
            xyz(p.pose.position),
            (*xyz(p.pose.orientation), p.pose.orientation.w),
        )
        for e in scene.entities
        for kind, group in (("cube", e.cubes), ("cylinder", e.cylinders), ("sphere", e.spheres))
        for p in group
    )
    assert primitives == sorted(
        (s.frame, s.kind, s.size, s.position, s.orientation) for s in shapes
    )
    assert sent.encode() == scene_message(2.5, shapes).encode()  # made alike each time
