"""`snakebot drive` without a terminal (--keys, --script) against the controller's C
device logic on a pty: the keys change Steering Offset and Speed Scale, space stops and
starts, the script ends stopped; and the errors a user meets first."""

from __future__ import annotations

import json
import math
import os
import pty
import tty

import pytest
from controller_cli_support import cli

from snakebot.facts.controller import load
from snakebot.link.controller.drive import STEER_STEP, Wait, parse_keys

SNAKE5_IDS = [10, 11, 15, 16]
_STEERING = load().register("Steering Offset")
STEP_TICKS = _STEERING.from_units(STEER_STEP, "rad")


def test_keys_parse_from_names_letters_and_waits():
    assert parse_keys("LLRR U space q") == ["left"] * 2 + ["right"] * 2 + ["up", "space", "q"]
    assert parse_keys("left Down 0.5s # a comment R\n D .25s quit") == [
        "left",
        "down",
        Wait(0.5),
        "down",
        Wait(0.25),
        "q",
    ]
    for bad, word in (("LX", "'LX'"), ("5", "'5'"), ("1e3s", "'1e3s'"), ("9999s", "longer")):
        with pytest.raises(ValueError, match=word):
            parse_keys(bad)


def records(result) -> list[dict]:
    assert result.exit_code == 0, result.output
    return [json.loads(line) for line in result.stdout.splitlines()]


def test_scripted_keys_steer_speed_stop_and_start(controller):
    keys = "LL 0.2s R U U D 0.2s space 0.2s space 0.2s"
    out = records(
        cli("drive", "--port", controller.device, "--robot", "snake5", "--keys", keys, "--json")
    )
    done = [(r.get("key"), r["state"]) for r in out]
    assert done == [
        ("left", "SERPENOID"),
        ("left", "SERPENOID"),
        (None, "SERPENOID"),
        ("right", "SERPENOID"),
        ("up", "SERPENOID"),
        ("up", "SERPENOID"),
        ("down", "SERPENOID"),
        (None, "SERPENOID"),
        ("space", "IDLE"),
        (None, "IDLE"),
        ("space", "SERPENOID"),
        (None, "SERPENOID"),
        ("q", "IDLE"),  # the script ends as q does: stopped
    ]
    # the controller's own registers, read back after each key
    steer = [round(math.radians(r["steer_deg"]) / STEER_STEP) for r in out]
    assert steer[:4] == [1, 2, 2, 1]
    assert [r["speed"] for r in out[4:8]] == [1.25, 1.5, 1.25, 1.25]
    for r in out:
        assert [j["id"] for j in r["joints"]] == SNAKE5_IDS
        assert [j["name"] for j in r["joints"]] == ["phi1", "phi2", "phi3", "phi4"]
        assert r["error_flags"] == []
    # the joints move while the serpenoid runs and hold while stopped
    moving = {j["name"]: j["goal_deg"] for j in out[7]["joints"]}
    assert moving != {j["name"]: j["goal_deg"] for j in out[2]["joints"]}
    held = [[j["goal_deg"] for j in r["joints"]] for r in out[8:10]]
    assert held[0] == held[1]
    assert controller.state() == load().enums["State"]["IDLE"]


def test_a_script_file_and_the_text_report(controller, tmp_path):
    script = tmp_path / "turn.keys"
    script.write_text("# turn left twice, then quit\nL L\nq\nR  # never pressed: q quit\n")
    result = cli("drive", "--port", controller.device, "--robot", "snake5", "--script", script)
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert len(lines) == 3
    assert "left: steer left" in lines[0] and "SERPENOID" in lines[0]
    assert (
        f"steering {math.degrees(_STEERING.to_units(2 * STEP_TICKS, 'rad')):+.1f} deg" in lines[1]
    )
    assert "q: stopped, quit" in lines[2] and "IDLE" in lines[2]
    assert "phi1" in lines[0] and "phi4" in lines[0]


def test_steering_stops_at_the_end_of_what_the_controller_allows(controller):
    # the register's own range or, first, the controller's check that the running wave
    # stays inside every joint's limits (Refusal Reason AMPLITUDE): never an error
    low, high = _STEERING.value_range()
    presses = high // STEP_TICKS + 2
    out = records(
        cli(
            "drive",
            "--port",
            controller.device,
            "--robot",
            "snake5",
            "--keys",
            "L" * presses,
            "--json",
        )
    )
    done = out[-2]["done"]
    assert "end of the range" in done or "Refusal Reason AMPLITUDE" in done, done
    assert _STEERING.from_units(math.radians(out[-2]["steer_deg"]), "rad") <= high


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--keys", "L X q"], ["--keys", "unknown key 'X'", "0.5s"]),
        (["--keys", "q", "--script", "{script}"], ["--keys or --script, not both"]),
        ([], ["needs a terminal", "--keys"]),
        (["--script", "{missing}"], ["--script", "does not exist"]),
        (["--keys", "L", "-A", "much"], ["--amplitude"]),
    ],
)
def test_bad_input_is_one_line_and_exit_2(controller, tmp_path, args, words):
    script = tmp_path / "k"
    script.write_text("q")
    args = [a.format(script=script, missing=tmp_path / "none") for a in args]
    result = cli("drive", "--port", controller.device, *args)
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith("error: ") and len(result.stderr.splitlines()) == 1
    for word in words:
        assert word in result.stderr, word
    assert controller.state() == load().enums["State"]["IDLE"]  # nothing was started


def test_a_missing_port_and_nothing_answering(tmp_path):
    port = str(tmp_path / "ttyUSB9")
    result = cli("drive", "--port", port, "--keys", "q")
    assert result.exit_code == 2
    assert result.stderr.startswith(f"error[E101]: serial port {port} does not exist")
    master, slave = pty.openpty()  # a port with nobody behind it
    tty.setraw(slave)
    try:
        result = cli(
            "drive", "--port", os.ttyname(slave), "--keys", "q", env={"SNAKEBOT_RETRIES": "0"}
        )
    finally:
        os.close(master)
        os.close(slave)
    assert result.exit_code == 1
    assert result.stderr.startswith("error[E301]: --baud, --id: the controller (ID 200) on ")
    assert len(result.stderr.splitlines()) == 1 and "Traceback" not in result.output


def test_help_names_the_keys_and_modes():
    result = cli("drive", "--help")
    assert result.exit_code == 0
    for word in ("--keys", "--script", "--json", "--robot", "space", "q", "arrows"):
        assert word in result.stdout, word
