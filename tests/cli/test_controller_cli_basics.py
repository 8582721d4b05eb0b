"""Every controller command's --help, and the errors a user meets first: a port that
does not exist, and a port with nothing answering on it."""

from __future__ import annotations

import os
import pty
import tty

import pytest
from controller_cli_support import cli, save, wave_table

COMMANDS = {
    "upload": ["GAIT", "CRC-32", "--port", "--baud", "--id", "--json", "--new-servos"],
    "play": ["--loop / --once", "--speed", "--steer", "deg", "--port"],
    "stop": ["--clear", "--port"],
    "serpenoid": ["--amplitude", "--omega", "--delta", "--offset", "--steer", "--robot", "deg"],
    "monitor": ["--duration", "--interval", "--json", "JSON Lines", "--port"],
}


@pytest.mark.parametrize("command", COMMANDS)
def test_help_works_and_names_the_options(command):
    result = cli(command, "--help")
    assert result.exit_code == 0
    for word in COMMANDS[command]:
        assert word in result.stdout, word


def _args(command: str, tmp_path) -> list[str]:
    if command == "upload":
        return [str(save(wave_table(), tmp_path))]
    if command == "serpenoid":
        return ["-A", "0.3", "-w", "3", "-d", "1"]
    return []


@pytest.mark.parametrize("command", COMMANDS)
def test_a_missing_port_is_one_line_and_exit_2(command, tmp_path):
    port = str(tmp_path / "ttyUSB9")
    result = cli(command, *_args(command, tmp_path), "--port", port)
    assert result.exit_code == 2
    assert result.stderr.startswith(f"error[E101]: serial port {port} does not exist")
    assert "Traceback" not in result.output


@pytest.mark.parametrize("command", COMMANDS)
def test_nothing_answering_names_the_controller_and_the_checks(command, tmp_path):
    master, slave = pty.openpty()  # a port with nobody behind it
    tty.setraw(slave)
    try:
        result = cli(
            command,
            *_args(command, tmp_path),
            "--port",
            os.ttyname(slave),
            env={"SNAKEBOT_RETRIES": "0"},
        )
    finally:
        os.close(master)
        os.close(slave)
    assert result.exit_code == 1  # a runtime failure: the input was fine
    err = result.stderr
    assert err.startswith("error[E301]: --baud, --id: the controller (ID 200) on ")
    assert "did not answer" in err and "snakebot firmware" in err and "the baud rate" in err


def test_a_port_is_required():
    result = cli("play")
    assert result.exit_code == 2
    assert "--port" in result.stderr
