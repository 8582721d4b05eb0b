"""`snakebot play`, `stop` and `serpenoid` against the controller's real C device logic
behind a pty: the State register follows the commands, values are converted and
range-checked, and a gait that cannot start says why."""

from __future__ import annotations

import math
import time

import pytest
from controller_cli_support import (
    SNAKE5_IDS,
    cli,
    cli_json,
    constant_table,
    monitor_records,
    save,
    wave_table,
)

from snakebot.link.controller import State
from snakebot.sim.controller_pty import ControllerPty
from snakebot.sim.servo.fast import VirtualServo

TICKS_PER_DEG = 1023 / 300


def test_play_then_stop_changes_the_state_register(controller_with_table):
    server = controller_with_table
    assert server.state() == State.IDLE
    played = cli_json("play", "--port", server.device)
    assert played["state"] == "PLAYING" and server.state() == State.PLAYING
    assert played["loop"] is True  # the table's own flag
    stopped = cli_json("stop", "--port", server.device)
    assert stopped["state"] == "IDLE" and server.state() == State.IDLE


def test_play_applies_speed_steering_and_once(controller_with_table):
    server = controller_with_table
    played = cli_json(
        "play", "--port", server.device, "--speed", "0.5", "--steer", "10deg", "--once"
    )
    assert played["speed"] == 0.5
    assert played["steering_offset_ticks"] == round(10 * TICKS_PER_DEG)
    assert played["loop"] is False
    # the constant table at 300, steered by +10 deg on every (forward-mounted) joint
    goals = {s["goal"] for s in monitor_records(server.device, 0.2)[-1]["servos"]}
    assert goals == {300 + round(10 * TICKS_PER_DEG)}


def test_text_output_says_what_plays_and_how_to_stop(controller_with_table):
    result = cli("play", "--port", controller_with_table.device, "--steer", "-0.1")
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith("PLAYING: the table (100 frames x 4 joints every 20 ms")
    ticks = round(math.degrees(-0.1) * TICKS_PER_DEG)  # what the controller holds
    assert f"steering {ticks / TICKS_PER_DEG:+.1f} deg" in result.stdout
    assert "snakebot stop --port" in result.stdout


def test_play_without_a_table_is_refused_with_the_fix(controller):
    result = cli("play", "--port", controller.device)
    assert result.exit_code == 2
    assert "no gait table" in result.stderr and "snakebot upload" in result.stderr
    assert controller.state() == State.IDLE


@pytest.mark.parametrize(
    "args, words",
    [
        (["play", "--speed", "5"], "--speed: speed 5 is outside what the controller takes"),
        (["play", "--speed", "0"], "--speed: speed 0 is outside"),
        (["play", "--steer", "160deg"], "--steer: steer 2.793 rad (160 deg) is outside"),
        (["serpenoid", "-A", "151deg", "-w", "1", "-d", "1"], "--amplitude"),
        (["serpenoid", "-A", "0.5", "-w", "40", "-d", "1"], "--omega: omega 40 rad/s"),
        (["serpenoid", "-A", "0.5", "-w", "1", "-d", "7"], "--delta: delta 7 rad"),
        (
            ["serpenoid", "-A", "0.5", "-w", "1", "-d", "1", "--offset", "-3"],
            "--offset: offset -3 rad",
        ),
    ],
)
def test_values_outside_the_control_table_are_refused_before_sending(
    controller_with_table,
    args,
    words,
):
    server = controller_with_table
    result = cli(*args, "--port", server.device)
    assert result.exit_code == 2
    assert words in result.stderr and "nothing was changed" in result.stderr
    assert server.host_packets == []
    assert server.state() == State.IDLE


def test_serpenoid_runs_on_the_roster_and_follows_the_wave(controller_with_table):
    server = controller_with_table
    status = cli_json(
        "serpenoid",
        "--port",
        server.device,
        "-A",
        "20deg",
        "-w",
        "360deg",
        "-d",
        "90deg",
        "--offset",
        "2deg",
    )
    assert status["state"] == "SERPENOID" and server.state() == State.SERPENOID
    s = status["serpenoid"]
    assert s["amplitude_rad"] == pytest.approx(math.radians(20), abs=1e-3)
    assert s["omega_rad_s"] == pytest.approx(math.radians(360), abs=1e-3)
    assert s["delta_rad"] == pytest.approx(math.radians(90), abs=1e-3)
    assert s["offset_rad"] == pytest.approx(math.radians(2), abs=1e-3)
    records = monitor_records(server.device, duration=0.4, interval=0.1)
    joint0 = [r["servos"][0]["goal"] for r in records[1:]]
    assert len(set(joint0)) > 1  # the goals move with the wave
    amplitude_ticks = math.radians(20) * 1023 / math.radians(300)
    offset_ticks = math.radians(2) * 1023 / math.radians(300)
    for goal in joint0:
        assert abs(goal - 512 - offset_ticks) <= amplitude_ticks + 1
    assert cli_json("stop", "--port", server.device)["state"] == "IDLE"


def test_serpenoid_with_an_empty_roster_asks_for_a_robot(controller):
    result = cli("serpenoid", "--port", controller.device, "-A", "0.3", "-w", "3", "-d", "1")
    assert result.exit_code == 2
    assert "roster is empty" in result.stderr and "--robot" in result.stderr
    status = cli_json(
        "serpenoid",
        "--port",
        controller.device,
        "-A",
        "0.3",
        "-w",
        "3",
        "-d",
        "1",
        "--robot",
        "snake5",
    )
    assert status["state"] == "SERPENOID" and status["joint_count"] == 4
    ids = [s["id"] for s in monitor_records(controller.device)[0]["servos"]]
    assert tuple(ids) == SNAKE5_IDS


def test_the_safe_state_refuses_play_and_stop_clear_leaves_it(tmp_path):
    # the table names servo 16, which is not on the bus: telemetry misses -> BUS_LOSS
    table = constant_table(512)
    with ControllerPty(servo_ids=(10, 11, 15), table=table.encode()) as server:
        deadline = time.monotonic() + 5
        while server.state() != State.SAFE and time.monotonic() < deadline:
            time.sleep(0.02)
        assert server.state() == State.SAFE
        result = cli("play", "--port", server.device)
        assert result.exit_code == 1  # a runtime state, not bad input (issue #28)
        assert "safe state" in result.stderr
        assert "BUS_LOSS (a roster servo stopped answering" in result.stderr
        assert "check the servos' power" in result.stderr
        assert "snakebot stop --clear" in result.stderr
        # the missing servo is plugged in: stop --clear leaves the safe state for good
        with server.lock:
            server.bus.add(VirtualServo(16))
        status = cli_json("stop", "--port", server.device, "--clear")
        assert status["state"] == "IDLE" and status["error_flags"] == []
        time.sleep(0.2)  # many telemetry rounds: the fault does not come back
        assert cli_json("play", "--port", server.device)["state"] == "PLAYING"


def test_serpenoid_keeps_running_a_table_uploaded_roster(controller, tmp_path):
    path = save(wave_table(), tmp_path)
    assert cli("upload", path, "--port", controller.device).exit_code == 0
    status = cli_json("serpenoid", "--port", controller.device, "-A", "0.2", "-w", "2", "-d", "1.5")
    assert status["state"] == "SERPENOID" and status["joint_count"] == 4
