"""`snakebot sim serve --foxglove`: the emulated robot (its firmware in QEMU) streamed to a
real WebSocket client speaking the Foxglove protocol (issue #33); on the mujoco world, its
bodies as a foxglove.SceneUpdate too."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest
from firmware_support import QEMU_DIR, REPO_ROOT, build_firmware
from foxglove_client import SUBPROTOCOLS, advertised, decode, subscribe

pytest.importorskip("foxglove")
websockets_sync = pytest.importorskip("websockets.sync.client")

pytestmark = [pytest.mark.qemu, pytest.mark.slow]


@pytest.mark.parametrize("world", ["kinematic", "mujoco"])
def test_serve_streams_the_emulated_joints_to_foxglove(world):
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
            "--firmware",
            str(QEMU_DIR / "firmware.elf"),
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
    topics = ["/joint_states", "/scene"] if world == "mujoco" else ["/joint_states"]
    try:
        first = json.loads(serve.stdout.readline())
        assert first["event"] == "serving"
        url = first["foxglove"]
        assert url.startswith("ws://127.0.0.1:")  # loopback unless a host is given
        got: dict[str, dict] = {}
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
        if world == "mujoco":  # the bodies, each locked to its link's frame on /tf
            entities = {e["frame_id"]: e for e in got["/scene"]["entities"]}
            links = {f"link{k}" for k in range(2, 6)} | {"base"}
            assert set(entities) == links | {f"wheel{k}" for k in range(1, 6)}
            assert all(e["frame_locked"] for e in entities.values())
            assert sum(len(e["cubes"]) for e in entities.values()) == 5
            assert all(len(entities[w]["cylinders"]) == 1 for w in set(entities) - links)
    finally:
        serve.send_signal(signal.SIGTERM)
        serve.communicate(timeout=30)
    assert serve.returncode == 143
