"""The physics world's bodies as a 3-D scene (Foxglove's /scene on `sim serve --world
mujoco`): real MuJoCo, the robot's geoms in the world frame, moving with the body."""

from __future__ import annotations

import math

import pytest

from snakebot.formats.live_topics import scene_message
from snakebot.link.transport import DxlClient
from snakebot.model.robots import load_robot
from snakebot.sim.physics import PhysicsWorld
from snakebot.workflows.predict import sim_url

pytest.importorskip("mujoco")
SNAKE5 = load_robot("snake5")


def test_the_scene_is_the_bodies_where_the_world_has_them():
    client = DxlClient(sim_url(SNAKE5, False), echo=False)
    try:
        world = PhysicsWorld(client.port.bus, SNAKE5, pose=(1.0, 0.5, math.pi / 2))
        shapes = world.shapes()
    finally:
        client.close()
    links = [s for s in shapes if s.kind == "cube"]
    wheels = [s for s in shapes if s.kind == "cylinder"]
    assert len(links) == SNAKE5.n_joints + 1 and len(wheels) == SNAKE5.n_wheels
    # straight at rest, heading +y from (1.0, 0.5): every link on the line x = 1.0
    for link in links:
        assert link.position[0] == pytest.approx(1.0, abs=1e-6)
        assert link.position[1] > 0.5
        x, y, z, w = link.orientation
        assert (z, w) == pytest.approx((math.sin(math.pi / 4), math.cos(math.pi / 4)), abs=1e-6)
    first = min(links, key=lambda s: s.position[1])  # link 1, its tail end at the pose
    assert first.size[0] == pytest.approx(2 * SNAKE5.l * SNAKE5.physics.unit_m)
    assert first.position[1] == pytest.approx(0.5 + first.size[0] / 2, abs=1e-6)
    message = scene_message(2.5, shapes)
    (entity,) = message["entities"]
    assert entity["frame_id"] == "odom" and entity["timestamp"] == {
        "sec": 2,
        "nanosec": 500_000_000,
    }
    assert len(entity["cubes"]) == len(links) and len(entity["cylinders"]) == len(wheels)
