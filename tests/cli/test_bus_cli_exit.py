"""`snakebot bus` exit statuses: a command line that cannot be carried out is bad input
(2, before the port is opened); servos that do not answer or do not take a change are a
runtime failure (1). Each failure is one ``error:`` line that says what to check."""

from __future__ import annotations

import itertools

import pytest
from click.testing import CliRunner

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli import main
from snakebot.cli.troubleshooting import ERROR_LINE
from snakebot.sim.urlhandler.protocol_sim import forget_named_buses

pytestmark = pytest.mark.timeout(120)

MISSING_PORT = "/dev/ttySNAKEBOT-missing"
_names = itertools.count()


@pytest.fixture(autouse=True)
def steady_timing(monkeypatch):
    monkeypatch.setenv("SNAKEBOT_LATENCY_MS", "30")  # room for a busy machine
    yield
    forget_named_buses()


def bus(*args: str):
    return CliRunner().invoke(main, ["bus", *args])


def one_error_line(result) -> str:
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and ERROR_LINE.match(lines[0]), result.stderr
    return lines[0]


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["ping", "3"], "no reply from servo 3 at 1000000 baud"),
        (["read", "3", "present-position"], "no reply to READ to servo 3"),
        (["write", "3", "led", "1"], "no reply to READ to servo 3"),
        (["set-id", "3", "4"], "no servo answers at ID 3"),
        (["set-baud", "3", "500000"], "no servo answers at ID 3"),
    ],
)
def test_a_servo_that_does_not_answer_is_a_runtime_failure(args, says):
    port = f"sim://quiet{next(_names)}?ids=1"  # only servo 1 is on this bus
    result = bus(*args, "--port", port)
    assert result.exit_code == 1, result.output
    line = one_error_line(result)
    assert says in line
    assert "baud" in line  # what to check: among others the rate the bus runs at


def test_ping_names_the_missing_servos_after_listing_the_found_ones():
    port = f"sim://quiet{next(_names)}?ids=1"
    result = bus("ping", "1", "2", "3", "--port", port)
    assert result.exit_code == 1
    assert "AX-12A" in result.stdout  # servo 1 is still reported
    line = one_error_line(result)
    assert "servos 2, 3" in line and "powered" in line and "snakebot bus scan" in line


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["set-id", "4", "4"], "ID and NEW_ID are both 4"),
        (["set-baud", "1", "300000"], "an AX-12 cannot run at 300000 bit/s"),
        (["write", "1", "goal-position", "1024"], "Goal Position takes 0-1023"),
        (["ping", "254"], "254"),
    ],
)
def test_a_command_line_that_cannot_be_carried_out_is_bad_input(args, says):
    # the port does not exist: these must be refused before it is opened
    result = bus(*args, "--port", MISSING_PORT)
    assert result.exit_code == 2, result.output
    assert says in one_error_line(result)
    assert "does not exist" not in result.stderr
