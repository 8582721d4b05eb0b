"""The robot live in Foxglove (issue #33): the real foxglove-sdk server, a real WebSocket
client speaking the Foxglove protocol (subprotocol foxglove.websocket.v1), the real MCAP
reader for the file written beside."""

from __future__ import annotations

import base64
import math
import threading
import time

import pytest
from foxglove_client import SUBPROTOCOLS, advertised, decode, subscribe

from snakebot.formats.live_topics import JSON_CHANNELS, TOPICS, JointSample, Shape
from snakebot.model.robots import load_robot
from snakebot.workflows.foxglove import FoxgloveLive, FoxgloveOptionError, parse_endpoint

pytest.importorskip("foxglove")
pytest.importorskip("google.protobuf")
websockets_sync = pytest.importorskip("websockets.sync.client")
SNAKE5 = load_robot("snake5")


def sample(k: int) -> JointSample:
    a = 0.1 * k
    return JointSample(
        names=[j.name for j in SNAKE5.joints],
        goal=[a, -a, 0.2, 0.0],
        present=[a - 0.01, -a, 0.19, 0.0],
        velocity=[0.5, -0.5, 0.0, 0.0],
        load=[0.25, -0.1, 0.0, 0.0],
        errors=[0, 0, 32, 0],
    )


BOX = Shape("cube", (0.14, 0.035, 0.035), (0.07, 0.0, 0.04), (0.0, 0.0, 0.0, 1.0))
WHEEL = Shape("cylinder", (0.04, 0.04, 0.01), (0.0, 0.0, 0.0), (-0.7071, 0.0, 0.0, 0.7071), "axle")


@pytest.fixture()
def live(tmp_path):
    server = FoxgloveLive(SNAKE5, "127.0.0.1", 0, mcap=tmp_path / "live.mcap")
    yield server
    server.close()


def test_a_client_sees_the_channels_and_decodes_the_joints_and_the_scene(live, tmp_path):
    stop = threading.Event()

    def publish():
        k = 0
        while not stop.is_set():
            live.publish(
                0.02 * k,
                sample(k % 5),
                (0.1, 0.2, math.pi / 2),
                {"state": "playing"},
                [BOX, WHEEL],
            )
            k += 1
            time.sleep(0.02)

    with websockets_sync.connect(
        f"ws://127.0.0.1:{live.port}", subprotocols=SUBPROTOCOLS, open_timeout=10
    ) as ws:
        assert ws.subprotocol in SUBPROTOCOLS
        assert ws.recv(timeout=10)  # serverInfo
        channels = advertised(ws, set(TOPICS))
        assert set(channels) == set(TOPICS)
        assert {channels[t]["encoding"] for t in JSON_CHANNELS} == {"json"}
        # the bodies in Foxglove's own SceneUpdate: the SDK's protobuf schema
        scene_channel = channels["/scene"]
        assert (scene_channel["encoding"], scene_channel["schemaName"]) == (
            "protobuf",
            "foxglove.SceneUpdate",
        )
        wanted = subscribe(ws, channels, ["/joint_states", "/snakebot/servos", "/tf", "/scene"])
        thread = threading.Thread(target=publish, daemon=True)
        thread.start()
        got: dict = {}
        try:
            deadline = time.monotonic() + 10
            while len(got) < len(wanted) and time.monotonic() < deadline:
                message = decode(ws.recv(timeout=10), wanted)
                if message is not None:
                    got[message[0]] = message[1]
        finally:
            stop.set()
            thread.join()
    joints = got["/joint_states"]
    assert joints["name"] == [j.name for j in SNAKE5.joints]
    k = round(joints["position"][0] / 0.1 + 0.1)  # which sample it was
    expected = sample(k)
    assert joints["position"] == pytest.approx(list(expected.present))
    assert joints["velocity"] == pytest.approx(list(expected.velocity))
    assert joints["effort"] == pytest.approx([v * live.stall_nm for v in expected.load])
    servos = got["/snakebot/servos"]
    assert servos["error"] == [0, 0, 32, 0] and len(servos["goal"]) == 4
    frames = {t["child_frame_id"]: t for t in got["/tf"]["transforms"]}
    base = frames["base"]
    assert base["parent_frame_id"] == "odom"
    assert base["translation"]["x"] == pytest.approx(0.1)  # snake5 is in metres
    assert base["rotation"]["z"] == pytest.approx(math.sin(math.pi / 4))
    assert {"link2", "wheel1"} <= set(frames)  # the links, for the URDF in the 3-D panel
    odom, axle = got["/scene"].entities  # one entity per frame, locked to it
    assert (odom.id, odom.frame_id, odom.frame_locked) == ("robot/odom", "odom", True)
    assert (axle.id, axle.frame_id, axle.frame_locked) == ("robot/axle", "axle", True)
    assert not odom.cylinders and not axle.cubes and not odom.spheres
    (cube,) = odom.cubes
    assert (cube.size.x, cube.size.y, cube.size.z) == pytest.approx(BOX.size)
    assert cube.pose.position.z == pytest.approx(0.04) and cube.pose.orientation.w == 1
    assert cube.color.a == 1  # drawn, not transparent
    (wheel,) = axle.cylinders
    assert (wheel.size.x, wheel.size.y, wheel.size.z) == pytest.approx(WHEEL.size)
    assert (wheel.bottom_scale, wheel.top_scale) == (1, 1)  # a cylinder, not a cone
    assert wheel.pose.orientation.x == pytest.approx(-0.7071)

    live.close()
    from mcap.reader import make_reader

    with open(tmp_path / "live.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    recorded = {c.topic: (c, summary.schemas[c.schema_id]) for c in summary.channels.values()}
    assert set(recorded) == set(TOPICS)
    assert all(n >= 1 for n in summary.statistics.channel_message_counts.values())
    for topic, (channel, schema) in recorded.items():  # the file has what the server served
        served = channels[topic]
        assert (channel.message_encoding, schema.name) == (served["encoding"], served["schemaName"])
        assert schema.encoding == served["schemaEncoding"]
        data = served["schema"]
        assert schema.data == (
            base64.b64decode(data) if schema.encoding == "protobuf" else data.encode()
        )


@pytest.mark.parametrize(
    ("text", "expected"),
    [("8765", ("127.0.0.1", 8765)), ("0.0.0.0:9000", ("0.0.0.0", 9000)), ("[::1]:0", ("::1", 0))],
)
def test_endpoints_are_loopback_unless_a_host_is_given(text, expected):
    assert parse_endpoint(text) == expected


@pytest.mark.parametrize("text", ["", "http", "70000", "host:"])
def test_bad_endpoints_are_refused(text):
    with pytest.raises(FoxgloveOptionError, match="HOST"):
        parse_endpoint(text)


def test_only_the_topics_a_client_takes_are_built_and_sent():
    with FoxgloveLive(SNAKE5, "127.0.0.1", 0) as server:
        assert server.watched() == set()  # no client, no file: nothing worth building
        with websockets_sync.connect(
            f"ws://127.0.0.1:{server.port}", subprotocols=SUBPROTOCOLS, open_timeout=10
        ) as ws:
            ws.recv(timeout=10)  # serverInfo
            wanted = subscribe(ws, advertised(ws, {"/tf"}), ["/tf"])
            deadline = time.monotonic() + 10
            while server.watched() != {"/tf"} and time.monotonic() < deadline:
                time.sleep(0.01)
            assert server.watched() == {"/tf"}
            server.publish(0.5, sample(1), (0.1, 0.2, 0.0))
            got = None
            while got is None:
                got = decode(ws.recv(timeout=10), wanted)
    assert got[0] == "/tf"
    messages = server.messages.moment(0.5, sample(1), None, topics={"/joint_states"})
    assert [topic for topic, _ in messages] == ["/joint_states"]
