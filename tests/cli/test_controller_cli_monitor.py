"""`snakebot monitor` against the controller's real C device logic behind a pty, with
emulated servos on its bus: JSON Lines records, the text table, and refreshing in place
on a terminal."""

from __future__ import annotations

import csv
import json
import math
import os
import pty
import subprocess
import sys
import time

import pytest
from controller_cli_support import (
    cli,
    cli_json,
    monitor_records,
)

from snakebot.link.controller import State
from snakebot.link.controller.monitor import CSV_COLUMNS
from snakebot.model.robots import load_robot
from snakebot.paths import REPO_ROOT

SNAKE5 = load_robot("snake5")

SERVO_FIELDS = {
    "joint",
    "name",
    "id",
    "goal",
    "goal_deg",
    "position",
    "position_deg",
    "speed_rpm",
    "load",
    "load_percent",
    "voltage_v",
    "temperature_c",
    "error",
    "error_count",
    "timeout_count",
    "reverse",
    "zero_tick",
    "min_tick",
    "max_tick",
}


def test_json_lines_have_the_controller_and_every_servo(controller_with_table):
    server = controller_with_table
    cli_json("play", "--port", server.device)
    time.sleep(0.1)  # telemetry reads one servo a tick: let every servo be read once
    records = monitor_records(server.device, duration=0.5, interval=0.1)
    assert len(records) >= 3  # 6 on time; --duration ends on the clock if the host is slow
    times = [r["t"] for r in records]
    assert times == sorted(times) and times[-1] >= 0.2
    for record in records:
        c = record["controller"]
        assert c["state"] == "PLAYING" and c["error_flags"] == []
        assert c["table_bytes"] == len(server.active_table())
        assert [s["id"] for s in record["servos"]] == [10, 11, 15, 16]
        assert [s["name"] for s in record["servos"]] == ["phi1", "phi2", "phi3", "phi4"]
        # angles as the robot description converts its joints' ticks
        for joint, servo in zip(SNAKE5.joints, record["servos"], strict=True):
            for tick, deg in (
                (servo["position"], servo["position_deg"]),
                (servo["goal"], servo["goal_deg"]),
            ):
                assert deg == pytest.approx(math.degrees(joint.tick_to_angle(tick)), abs=0.01)
        for servo in record["servos"]:
            assert set(servo) == SERVO_FIELDS
            assert servo["voltage_v"] == 12.0  # the emulated supply
            assert 0 < servo["temperature_c"] < 80
            assert servo["error"] == [] and servo["timeout_count"] == 0
    # the servos move toward the table's 300: positions change from sample to sample
    first = [s["position"] for s in records[0]["servos"]]
    last = [s["position"] for s in records[-1]["servos"]]
    assert all(abs(b - 300) < abs(a - 300) or b == 300 for a, b in zip(first, last, strict=True))
    assert records[-1]["controller"]["bus_reads"] > records[0]["controller"]["bus_reads"]


def test_a_missing_servo_shows_up_as_timeouts(tmp_path):
    from controller_cli_support import constant_table

    from snakebot.sim.controller_pty import ControllerPty

    with ControllerPty(servo_ids=(10, 11, 15), table=constant_table(512).encode()) as server:
        deadline = time.monotonic() + 5  # 5 missed reads of servo 16, one read a tick
        while server.state() != State.SAFE and time.monotonic() < deadline:
            time.sleep(0.02)
        record = monitor_records(server.device)[0]
        by_id = {s["id"]: s for s in record["servos"]}
        assert by_id[16]["timeout_count"] > 0 and by_id[10]["timeout_count"] == 0
        assert record["controller"]["state"] == "SAFE"
        assert "BUS_LOSS" in record["controller"]["error_flags"]
        text = cli("monitor", "--port", server.device, "--duration", "0").stdout
        assert "state SAFE" in text and "BUS_LOSS (a roster servo stopped answering" in text
        assert "reads unanswered" in text


def test_plain_text_without_a_terminal(controller_with_table):
    result = cli(
        "monitor", "--port", controller_with_table.device, "--duration", "0.1", "--interval", "0.1"
    )
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "\x1b[" not in out  # no cursor movement when not on a terminal
    assert out.count("state IDLE") == 2  # two samples, one after the other
    assert "joint   ID  goal   pos" in out and "error flags: none" in out
    # every column's unit, on the line under the names
    assert "tick  tick       deg        rpm       %     V  degC" in out


def test_an_empty_roster_is_explained(controller):
    out = cli("monitor", "--port", controller.device, "--duration", "0").stdout
    assert "no servos in the roster" in out


def test_refreshes_in_place_on_a_terminal(controller_with_table):
    master, slave = pty.openpty()
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(REPO_ROOT / "host"), str(REPO_ROOT / "sim")]),
    }
    try:
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "snakebot",
                "monitor",
                "--port",
                controller_with_table.device,
                "--duration",
                "0.2",
                "--interval",
                "0.1",
            ],
            stdout=slave,
            stderr=subprocess.PIPE,
            env=env,
            timeout=60,
        )
        os.close(slave)
        slave = -1
        out = b""
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:
                break
            if not chunk:
                break
            out += chunk
    finally:
        os.close(master)
        if slave >= 0:
            os.close(slave)
    assert proc.returncode == 0, proc.stderr
    text = out.decode()
    assert text.count("state IDLE") == 3
    assert "\x1b[J" in text and "F\x1b[J" in text  # cursor up over the last table, clear


def _long_snake(path, joints: int) -> None:
    """A robot file with ``joints`` joints, alternate ones mounted the other way round."""
    text = (
        f'name = "long"\nkind = "snake"\n[geometry]\nlinks = {joints + 1}\n'
        'half_link = 0.07\n[friction]\nlateral = 0.8\nrolling = 0.01\n[servo]\nmodel = "AX-12A"\n'
    )
    for k in range(joints):
        text += (
            f'[[joints]]\nname = "phi{k + 1}"\nservo_id = {k + 1}\n'
            f"zero_tick = {500 + k}\nsign = {1 if k % 2 == 0 else -1}\n"
            "min_deg = -60.0\nmax_deg = 60.0\n"
        )
    path.write_text(text)


def test_rosters_longer_than_one_servo_page(tmp_path):
    from snakebot.sim.controller_pty import ControllerPty

    robot = tmp_path / "long.toml"
    _long_snake(robot, 8)
    with ControllerPty(servo_ids=tuple(range(1, 9))) as server:
        status = cli_json(
            "serpenoid",
            "--port",
            server.device,
            "--robot",
            str(robot),
            "-A",
            "10deg",
            "-w",
            "90deg",
            "-d",
            "45deg",
        )
        assert status["state"] == "SERPENOID" and status["joint_count"] == 8
        time.sleep(0.15)  # one telemetry round over 8 servos
        servos = monitor_records(server.device)[0]["servos"]
    assert [s["id"] for s in servos] == list(range(1, 9))  # pages 0 and 1
    assert [s["joint"] for s in servos] == list(range(8))
    assert all(s["voltage_v"] == 12.0 for s in servos)
    # the roster as the robot file describes it
    assert [s["zero_tick"] for s in servos] == [500 + k for k in range(8)]
    assert [s["reverse"] for s in servos] == [k % 2 == 1 for k in range(8)]
    span = round(60 * 1023 / 300)
    assert all(s["max_tick"] - s["min_tick"] == 2 * span for s in servos)


def test_csv_records_every_sample_one_row_per_servo(controller_with_table, tmp_path):
    path = tmp_path / "run.csv"
    result = cli(
        "monitor", "--port", controller_with_table.device, "--duration", "0.2",
        "--interval", "0.1", "--csv", path, "--json",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    records = [json.loads(line) for line in result.stdout.splitlines()]
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == list(CSV_COLUMNS)
    # the same samples as the JSON Lines printed beside them, servo by servo
    expected = [(r["t"], s["name"], s["position"], s["position_deg"])
                for r in records for s in r["servos"]]  # fmt: skip
    got = [(float(r["t"]), r["name"], int(r["position"]), float(r["position_deg"])) for r in rows]
    assert got == expected and len(rows) == 3 * 4


def test_csv_to_an_unwritable_place_fails_before_connecting(tmp_path):
    result = cli(
        "monitor", "--port", "/dev/ttySNAKEBOT-missing", "--csv", tmp_path / "no" / "x.csv"
    )
    assert result.exit_code == 2
    assert "x.csv" in result.stderr and "Traceback" not in result.output


def test_csv_is_not_left_behind_when_the_controller_cannot_be_reached(tmp_path):
    path = tmp_path / "run.csv"
    result = cli("monitor", "--port", "/dev/ttySNAKEBOT-missing", "--csv", path)
    assert result.exit_code == 2 and result.stderr.startswith("error[E101]: ")
    assert not path.exists()


def test_mcap_holds_one_json_message_per_sample(controller_with_table, tmp_path):
    from mcap.reader import make_reader

    path = tmp_path / "run.mcap"
    result = cli(
        "monitor", "--port", controller_with_table.device, "--duration", "0.2",
        "--interval", "0.1", "--mcap", path, "--json",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    printed = [json.loads(line) for line in result.stdout.splitlines()]
    with path.open("rb") as f:
        messages = list(make_reader(f).iter_messages(topics=["/snakebot/telemetry"]))
    assert len(messages) == len(printed) == 3
    for (schema, channel, message), record in zip(messages, printed, strict=True):
        assert channel.topic == "/snakebot/telemetry" and channel.message_encoding == "json"
        assert schema.encoding == "jsonschema"
        assert json.loads(message.data) == record
    stamps = [m.log_time for _, _, m in messages]
    assert stamps == sorted(stamps) and stamps[-1] - stamps[0] >= 0.15e9  # wall-clock ns
