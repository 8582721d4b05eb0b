"""`snakebot sim serve --foxglove`: the emulated robot (its firmware in QEMU) streamed to a
real WebSocket client speaking the Foxglove protocol (issue #33)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest
from firmware_support import QEMU_DIR, REPO_ROOT, build_firmware

pytest.importorskip("foxglove")
websockets_sync = pytest.importorskip("websockets.sync.client")

pytestmark = [pytest.mark.qemu, pytest.mark.slow]
SUBPROTOCOLS = ["foxglove.websocket.v1", "foxglove.sdk.v1"]


def test_serve_streams_the_emulated_joints_to_foxglove():
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
            "--foxglove",
            "0",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        first = json.loads(serve.stdout.readline())
        assert first["event"] == "serving"
        url = first["foxglove"]
        assert url.startswith("ws://127.0.0.1:")  # loopback unless a host is given
        with websockets_sync.connect(url, subprotocols=SUBPROTOCOLS, open_timeout=10) as ws:
            channels: dict[str, int] = {}
            while "/joint_states" not in channels:
                message = json.loads(ws.recv(timeout=10))
                if message["op"] == "advertise":
                    channels.update({c["topic"]: c["id"] for c in message["channels"]})
            subscribe = [{"id": 7, "channelId": channels["/joint_states"]}]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subscribe}))
            while True:
                data = ws.recv(timeout=10)
                if isinstance(data, bytes) and data[0] == 1:
                    joints = json.loads(data[13:])
                    break
        assert joints["name"] == ["phi1", "phi2", "phi3", "phi4"]
        # the servos hold at their zero ticks after boot: the angles read 0
        assert joints["position"] == pytest.approx([0.0] * 4, abs=0.01)
    finally:
        serve.send_signal(signal.SIGTERM)
        serve.communicate(timeout=30)
    assert serve.returncode == 143
