"""A bus rate no servo runs at is bad input: refused at once (exit 2), not a scan whose
every unanswered ping waits for seconds (the CLI fuzz found `bus scan --baud 99` on
sim:// running for minutes)."""

from __future__ import annotations

import time

import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.formats.register_values import all_bauds


@pytest.mark.parametrize("command", [["scan"], ["ping", "1"], ["write", "1", "LED", "1"]])
@pytest.mark.parametrize("baud", ["1", "99", "5000"])
def test_a_rate_no_servo_runs_at_is_refused_at_once(command, baud):
    started = time.monotonic()
    result = CliRunner().invoke(
        main, ["bus", *command, "--port", "sim://?robot=snake3", "--baud", baud]
    )
    assert result.exit_code == 2, result.output
    assert f"no Dynamixel servo described runs at {baud} bit/s" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert time.monotonic() - started < 5.0


def test_every_rate_a_scan_covers_is_accepted():
    # --bauds all tabulates the described servos' rates: each one passes --baud
    for bps in all_bauds():
        result = CliRunner().invoke(
            main, ["bus", "ping", "1", "--port", "sim://?ids=1", "--baud", str(bps), "--json"]
        )
        assert "no Dynamixel servo described runs at" not in result.output, bps
