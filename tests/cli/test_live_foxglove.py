"""`--foxglove` on `monitor`, `drive` and `bus play` (issue #33): each command's Foxglove
server, read by a real WebSocket client speaking the Foxglove protocol while the command
runs against the controller's real C device logic (or an emulated bus): the channels
advertised, the joint states decoded and matched against what the command printed."""

from __future__ import annotations

import json
import math

import pytest
from controller_cli_support import cli, cli_json
from foxglove_client import Listener, free_port
from physics_support import snake5_serpenoid_file

from snakebot.formats.live_topics import JSON_CHANNELS, TOPICS
from snakebot.link.controller.mcap_log import TOPIC as TELEMETRY
from snakebot.model.robots import load_robot

pytest.importorskip("foxglove")
pytest.importorskip("websockets.sync.client")

SERVO_TOPICS = ["/joint_states", "/snakebot/servos", "/snakebot/controller", "/tf"]


def by_stamp(messages: list[dict]) -> dict[float, dict]:
    return {round(m["stamp"]["sec"] + m["stamp"]["nanosec"] / 1e9, 3): m for m in messages}


def test_monitor_streams_what_it_prints_and_records_the_same_channels(
    controller_with_table, tmp_path
):
    from mcap.reader import make_reader

    cli_json("play", "--port", controller_with_table.device, "--loop")
    port, path = free_port(), tmp_path / "run.mcap"
    listener = Listener(port, SERVO_TOPICS)
    result = cli(
        "monitor", "--port", controller_with_table.device, "--duration", "1.5",
        "--interval", "0.05", "--robot", "snake5", "--foxglove", str(port), "--mcap", path,
        "--json",
    )  # fmt: skip
    listener.stop()
    assert result.exit_code == 0, result.output
    assert f"ws://127.0.0.1:{port}" in result.stderr
    printed = {r["t"]: r for r in map(json.loads, result.stdout.splitlines())}
    assert set(TOPICS) <= set(listener.channels)
    servos = by_stamp(listener.messages["/snakebot/servos"])
    assert len(servos) >= 10
    moving = set()
    for t, message in servos.items():
        record = printed[t]  # the sample this message was made of
        assert message["name"] == [s["name"] for s in record["servos"]]
        goal = [math.radians(s["goal_deg"]) for s in record["servos"]]
        present = [math.radians(s["position_deg"]) for s in record["servos"]]
        assert message["goal"] == pytest.approx(goal, abs=1e-3)
        assert message["present"] == pytest.approx(present, abs=1e-3)
        assert message["load"] == pytest.approx(
            [s["load_percent"] / 100 for s in record["servos"]], abs=1e-3
        )
        moving.add(tuple(round(v, 3) for v in message["present"]))
    assert len(moving) > 3  # the gait plays: the joints move from sample to sample
    joints = listener.messages["/joint_states"][-1]
    assert joints["name"] == ["phi1", "phi2", "phi3", "phi4"] and len(joints["effort"]) == 4
    states = {m["state"] for m in listener.messages["/snakebot/controller"]}
    assert states == {r["controller"]["state"] for r in printed.values()}
    bases = [
        t
        for m in listener.messages["/tf"]
        for t in m["transforms"]
        if t["child_frame_id"] == "base"
    ]
    assert bases and bases[0]["parent_frame_id"] == "odom"
    moved = math.hypot(bases[-1]["translation"]["x"], bases[-1]["translation"]["y"])
    assert moved > 0.005  # the predicted pose follows the gait

    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        recorded = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
        counts = summary.statistics.channel_message_counts
    # the JSON topics, with the live server's schemas as served (not /scene: a controller
    # has no bodies to draw)
    assert set(recorded) == {TELEMETRY, *JSON_CHANNELS}
    for topic in JSON_CHANNELS:
        channel = listener.channels[topic]
        assert (recorded[topic].name, recorded[topic].encoding) == (
            channel["schemaName"],
            channel["schemaEncoding"],
        )
        assert json.loads(recorded[topic].data) == json.loads(channel["schema"])
    topics = {c.topic: counts.get(i, 0) for i, c in summary.channels.items()}
    assert all(topics[t] == len(printed) for t in SERVO_TOPICS)


def test_drive_streams_each_look_at_the_controller(controller):
    port = free_port()
    listener = Listener(port, SERVO_TOPICS)
    result = cli(
        "drive", "--port", controller.device, "--robot", "snake5", "--keys", "1s LL 0.5s q",
        "--json", "--foxglove", str(port),
    )  # fmt: skip
    listener.stop()
    assert result.exit_code == 0, result.output
    printed = [json.loads(line) for line in result.stdout.splitlines()]
    servos = listener.messages["/snakebot/servos"]
    # looks every 20 ms through the waits, not only at the keys (at least twice as many
    # as the printed looks, one per key, however loaded the machine)
    assert len(servos) >= 2 * len(printed), (len(servos), len(printed))
    for record in printed:  # each printed look went out as it was
        goal = [math.radians(j["goal_deg"]) for j in record["joints"]]
        present = [math.radians(j["position_deg"]) for j in record["joints"]]
        assert any(
            m["goal"] == pytest.approx(goal, abs=1e-3)
            and m["present"] == pytest.approx(present, abs=1e-3)
            for m in servos
        ), record
    assert len({tuple(round(v, 3) for v in m["present"]) for m in servos}) > 3  # it drove
    states = [m["state"] for m in listener.messages["/snakebot/controller"]]
    assert states[-1] == printed[-1]["state"]
    assert any(t["child_frame_id"] == "base" for t in listener.messages["/tf"][-1]["transforms"])


def test_bus_play_streams_the_servos_it_reads_back_and_the_predicted_pose(tmp_path):
    gait = snake5_serpenoid_file(tmp_path)  # its metadata names snake5
    port = free_port()
    listener = Listener(port, SERVO_TOPICS)
    # realtime=0: the bus runs in this thread, not handing each reply over from a thread
    # of its own while the test's client thread holds the interpreter (10x slower here);
    # ideal servos reach each goal at once, so the gait still moves them
    result = cli(
        "bus", "play", gait, "--port", "sim://?robot=snake5&ideal=1&realtime=0", "--json",
        "--foxglove", str(port),
    )  # fmt: skip
    listener.stop()
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    servos = listener.messages["/snakebot/servos"]
    assert len(servos) >= 50  # 2 s at 50 a second, give or take the client's start
    # ideal servos are where they were sent: present follows goal, and the goal is the table's
    for m in servos:
        assert m["present"] == pytest.approx(m["goal"], abs=0.02)
    amplitude = max(abs(v) for m in servos for v in m["goal"])
    assert amplitude == pytest.approx(math.radians(30), abs=0.02)
    last = listener.messages["/joint_states"][-1]
    snake5 = load_robot("snake5")
    held = [j.tick_to_angle(report["present_position"][str(j.servo_id)]) for j in snake5.joints]
    assert last["position"] == pytest.approx(held, abs=0.02)  # where the report says they hold
    assert {m["state"] for m in listener.messages["/snakebot/controller"]} == {"playing"}
    base = [t for t in listener.messages["/tf"][-1]["transforms"] if t["child_frame_id"] == "base"]
    assert base[0]["translation"]["x"] > 0.02  # the serpenoid crawls forward (metres)
