"""`snakebot upload FILE.prog` and `snakebot play` against the controller's real C device
logic behind a pty: the program is committed as PROGRAM, play runs it with PROGRAM_RUN,
and it ends on its own; a program the robot's servos cannot play is refused on the host
before anything is sent."""

from __future__ import annotations

import time
from pathlib import Path

from controller_cli_support import cli, cli_json

from snakebot.formats.program.files import read_program
from snakebot.link.controller import State

SPEC = """
robot = "snake5"
period_ms = 20
[[segment]]
kind = "periodic"
omega = 3.0
sin = [0.2, 0.2, 0.2, 0.2]
duration = 0.4
[[segment]]
kind = "serpenoid"
amplitude = 0.3
omega = 3.0
delta = 1.0
duration = 0.6
"""


def build(tmp_path: Path) -> Path:
    spec = tmp_path / "plan.toml"
    spec.write_text(SPEC)
    out = tmp_path / "plan.prog"
    assert cli("program", "build", spec, "-o", out).exit_code == 0
    return out


def test_upload_and_play_run_a_program_to_its_end(controller, tmp_path):
    server = controller
    prog = build(tmp_path)
    uploaded = cli_json("upload", prog, "--port", server.device)
    assert uploaded["kind"] == "program" and uploaded["bytes"] == prog.stat().st_size
    text = cli("play", "--port", server.device)
    assert text.exit_code == 0 and "the program (4 joints, a step every 20 ms)" in text.stdout
    assert server.state() == State.PLAYING
    time.sleep(read_program(prog).duration_s + 0.5)
    assert server.state() == State.IDLE  # it ended on its own
    again = cli_json("play", "--port", server.device)  # runs again from its first step
    assert again["program"] is True and again["state"] == "PLAYING"
    assert cli_json("stop", "--port", server.device)["state"] == "IDLE"


def test_a_damaged_program_file_is_refused_before_sending(controller, tmp_path):
    server = controller
    prog = build(tmp_path)
    data = bytearray(prog.read_bytes())
    data[-1] ^= 0x40
    prog.write_bytes(bytes(data))
    result = cli("upload", prog, "--port", server.device)
    assert result.exit_code == 2
    assert result.stderr.count("\n") == 1 and "CRC-32 does not match" in result.stderr
    assert not server.host_packets  # nothing was sent
    shown = cli("program", "show", prog)
    assert shown.exit_code == 2 and shown.stderr.startswith("error: ")
