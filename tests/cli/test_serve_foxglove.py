"""`snakebot sim serve --foxglove`: the emulated robot streamed to a real WebSocket client
speaking the Foxglove protocol (issue #33); on the mujoco world, its bodies as Foxglove's
own SceneUpdate too, decoded through the protobuf schema the server advertises and checked
against the MuJoCo model's geoms, moving with the robot on /tf. The kinematic world runs
beside the default board (the CM-530's image on the emulated STM32F103RE, in the server's
own process), MuJoCo's beside QEMU (a process of its own): the CM-530, MuJoCo and the
Foxglove server in one process, beside the other QEMU-stage worker, drew too few /tf
messages in the wave's second."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from firmware_support import REPO_ROOT, build_firmware
from foxglove_client import SUBPROTOCOLS, advertised, decode, in_frame, subscribe

from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.playback import SerpenoidSettings, roster_from_robot, serpenoid
from snakebot.model.robots import load_robot

pytest.importorskip("foxglove")
pytest.importorskip("google.protobuf")
websockets_sync = pytest.importorskip("websockets.sync.client")

pytestmark = [pytest.mark.qemu, pytest.mark.slow]


@pytest.mark.parametrize(("world", "board"), [("kinematic", "cm530"), ("mujoco", "qemu")])
def test_serve_streams_the_emulated_joints_to_foxglove(world, board):
    if world == "mujoco":
        pytest.importorskip("mujoco")
    build_firmware()
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT / "host"))
    serve = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "snakebot",
            "sim",
            "serve",
            "--board",
            board,
            "--json",
            "--report",
            "0",
            "--world",
            world,
            "--foxglove",
            "0",
        ],  # fmt: skip
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    topics = ["/joint_states", "/scene", "/tf"] if world == "mujoco" else ["/joint_states"]
    try:
        first = json.loads(serve.stdout.readline())
        assert first["event"] == "serving"
        url = first["foxglove"]
        assert url.startswith("ws://127.0.0.1:")  # loopback unless a host is given
        got: dict = {}
        with websockets_sync.connect(url, subprotocols=SUBPROTOCOLS, open_timeout=10) as ws:
            channels = advertised(ws, set(topics))
            wanted = subscribe(ws, channels, topics)
            while len(got) < len(topics):
                message = decode(ws.recv(timeout=10), wanted)
                if message is not None:
                    got[message[0]] = message[1]
            joints = got["/joint_states"]
            assert joints["name"] == ["phi1", "phi2", "phi3", "phi4"]
            # the servos hold at their zero ticks after boot: the angles read 0
            assert joints["position"] == pytest.approx([0.0] * 4, abs=0.01)
            if world == "mujoco":
                assert channels["/scene"]["schemaName"] == "foxglove.SceneUpdate"
                check_the_scene(got["/scene"])
                check_the_scene_moves(got["/scene"], ws, wanted, first["pc_link"])
    finally:
        serve.send_signal(signal.SIGTERM)
        serve.communicate(timeout=30)
    assert serve.returncode == 143


SNAKE5 = load_robot("snake5")


def model_geoms() -> dict[str, list[tuple[str, tuple[float, ...]]]]:
    """The MuJoCo model's geoms of snake5 (but the floor), by body: each geom's type and
    full size (a box's edges; a cylinder's diameter and length; a sphere's diameter)."""
    import mujoco

    from snakebot.sim.physics.mjcf import build_mjcf

    m = mujoco.MjModel.from_xml_string(build_mjcf(SNAKE5)[0])
    geoms: dict[str, list[tuple[str, tuple[float, ...]]]] = {}
    for g in range(m.ngeom):
        body = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.geom_bodyid[g])
        a, b, c = (2 * float(v) for v in m.geom_size[g])
        shape = {
            int(mujoco.mjtGeom.mjGEOM_BOX): ("cube", (a, b, c)),
            int(mujoco.mjtGeom.mjGEOM_CYLINDER): ("cylinder", (a, a, b)),
            int(mujoco.mjtGeom.mjGEOM_SPHERE): ("sphere", (a, a, a)),
        }.get(int(m.geom_type[g]))  # None for the floor's plane
        if shape is not None:
            geoms.setdefault(body, []).append(shape)
    return geoms


def primitives(entity) -> list[tuple[str, tuple[float, ...]]]:
    groups = {"cube": entity.cubes, "cylinder": entity.cylinders, "sphere": entity.spheres}
    return [(k, (p.size.x, p.size.y, p.size.z)) for k, group in groups.items() for p in group]


def check_the_scene(scene) -> None:
    """One entity per body, locked to the body's frame on /tf, its primitives the MuJoCo
    model's geoms of that body, at their sizes."""
    geoms = model_geoms()
    entities = {e.frame_id: e for e in scene.entities}
    assert set(entities) == set(geoms)
    assert all(e.frame_locked and e.id == f"robot/{f}" for f, e in entities.items())
    for frame, entity in entities.items():
        drawn, modelled = sorted(primitives(entity)), sorted(geoms[frame])
        assert [kind for kind, _ in drawn] == [kind for kind, _ in modelled], frame
        for (_, size), (_, geom) in zip(drawn, modelled, strict=True):
            assert size == pytest.approx(geom, abs=1e-9), frame


def check_the_scene_moves(scene, ws, wanted, pc_link: str) -> None:
    """A serpenoid started on the firmware: the bodies the scene locks to the links'
    frames move in the world as /tf carries them (the tail link's box swings round)."""
    (tail,) = next(e for e in scene.entities if e.frame_id == "link5").cubes
    centre = (tail.pose.position.x, tail.pose.position.y, tail.pose.position.z)
    frames: dict[str, dict] = {}
    drawn: list[np.ndarray] = []
    ctl = ControllerClient.open(pc_link)
    try:
        wave = SerpenoidSettings(amplitude=math.radians(30), omega=2 * math.pi, delta=1.5)
        serpenoid(ctl, wave, roster=roster_from_robot(SNAKE5))
        deadline = time.monotonic() + 1.0  # one period of the wave
        while time.monotonic() < deadline:
            message = decode(ws.recv(timeout=10), wanted)
            if message is None or message[0] != "/tf":
                continue
            frames |= {t["child_frame_id"]: t for t in message[1]["transforms"]}
            if "base" in frames and "link5" in frames:
                drawn.append(in_frame(frames, "link5", centre))  # where the panel draws it
        ctl.command("STOP")
    finally:
        ctl.close()
    assert len(drawn) > 20
    spread = np.ptp(np.array(drawn), axis=0)
    assert max(spread[:2]) > 0.01, spread  # it moved by more than a centimetre
