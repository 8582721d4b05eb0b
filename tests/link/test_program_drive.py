"""`snakebot drive` while the controller runs a program (the controller's C device logic
behind a pty): the keys steer and speed the program instead of starting the serpenoid,
its serpenoid segment's goals carry the steering, and space runs it again; `snakebot play
--speed` runs a program faster or slower."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from controller_cli_support import cli, cli_json

from snakebot.link.controller import State
from snakebot.link.controller.client import ControllerClient

SPEC = """
robot = "snake5"
period_ms = 20
[[segment]]
kind = "serpenoid"
amplitude = 0.3
omega = 1.0
delta = 1.0
duration = 60.0
"""


def test_drive_steers_a_running_program(controller, tmp_path: Path) -> None:
    spec = tmp_path / "plan.toml"
    spec.write_text(SPEC)
    prog = tmp_path / "plan.prog"
    assert cli("program", "build", spec, "-o", prog).exit_code == 0
    assert cli_json("upload", prog, "--port", controller.device)["kind"] == "program"
    assert cli_json("play", "--port", controller.device)["program"] is True
    keys = "LLLL 0.5s U space 0.2s space 0.2s"
    result = cli("drive", "--port", controller.device, "--keys", keys, "--json")
    assert result.exit_code == 0, result.output
    out = [json.loads(line) for line in result.stdout.splitlines()]
    # the program kept running (PLAYING, not SERPENOID) and took the keys
    assert [(r.get("key"), r["state"]) for r in out] == [
        ("left", "PLAYING"),
        ("left", "PLAYING"),
        ("left", "PLAYING"),
        ("left", "PLAYING"),
        (None, "PLAYING"),
        ("up", "PLAYING"),
        ("space", "IDLE"),
        (None, "IDLE"),
        ("space", "PLAYING"),  # run again from its start
        (None, "PLAYING"),
        ("q", "IDLE"),
    ]
    assert abs(out[4]["steer_deg"] - 20.0) < 0.3 and out[5]["speed"] == 1.25
    # the steering reached the goals: the wave (0.3 rad about 0) is shifted by 20 deg
    # on every joint (reversed ones the other way), beyond what the wave alone reaches
    goals = [j["goal_deg"] for j in out[4]["joints"]]
    assert max(abs(g) for g in goals) > 17.2 + 5
    assert controller.state() == State.IDLE


@pytest.mark.serial
@pytest.mark.parametrize(("speed", "state"), [("4", "DONE"), ("0.25", "RUNNING")])
def test_play_speed_runs_a_program_faster_or_slower(
    controller, tmp_path: Path, speed: str, state: str
) -> None:
    # a 2 s program: at 4x it is over well within 1.5 s, at a quarter still running
    spec = tmp_path / "plan.toml"
    spec.write_text(SPEC.replace("duration = 60.0", "duration = 2.0"))
    prog = tmp_path / "plan.prog"
    assert cli("program", "build", spec, "-o", prog).exit_code == 0
    assert cli_json("upload", prog, "--port", controller.device)["kind"] == "program"
    assert cli_json("play", "--port", controller.device, "--speed", speed)["program"] is True
    time.sleep(1.5)
    with ControllerClient.open(controller.device) as ctl:
        now = ctl.read("Program State")["Program State"]
    assert now == ctl.table.enums["Program State"][state]
