"""A library refusal about a value the user gave is led by the option it came through:
the library says what is wrong in its own words and names its parameter
(``SnakebotError.about``), the CLI names the option (``snakebot.cli.errors``). Each case
is refused before any work, in process."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from snakebot.cli import main

SERPENOID = ["gait", "serpenoid", "snake3", "-A", "20deg", "-w", "90deg", "-d", "90deg"]
SEARCH = ["gait", "search", "snake3", "--param", "omega=1", "--param", "delta=1"]


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (
            ["gait", "field", "trident", "--field", "g1"],
            "--duration: g1 has no bracket term: give the duration to follow it for",
        ),
        (
            ["gait", "field", "trident", "--field", "h1", "--duration", "0.1", "--periods", "2"],
            "--duration, --periods: give a duration or a number of periods, not both",
        ),
        (
            ["gait", "field", "trident", "--field", "g1", "--periods", "2"],
            "--periods, --field: a number of periods needs 1 or more and a bracket term",
        ),
        (
            ["gait", "field", "snake3", "--field", "g1", "--duration", "0.1", "--start", "0.2,0.2"],
            "--start: the start configuration [0.2, 0.2] is singular for snake3",
        ),
        (
            [*SERPENOID, "--cycles", "0.001"],
            "--rate, --cycles, --omega: the gait is shorter than two frames",
        ),
        (
            [*SERPENOID, "--cycles", "1000"],
            "--rate, --cycles, --omega: the gait needs 200000 frames but the controller holds",
        ),
        (["plan", "snake3", "--to", "1,0,0", "--from", "0.1"], "--from: the start needs 2 joint"),
        ([*SEARCH, "--param", "A=1", "--param", "A=2"], "--param: amplitude is given twice"),
        ([*SEARCH, "--param", "A=1:0:3"], "--param: 'A=1:0:3' is an empty range"),
        (
            [*SEARCH, "--param", "A=0.1:0.5:3", "--robust", "mass=1:2:2", "--world", "kinematic"],
            "--robust, --world: mass applies to the mujoco world, not the kinematic world",
        ),
    ],
)
def test_a_refusal_names_the_option_it_is_about(tmp_path, args, line):
    out = tmp_path / ("out.csv" if args[1] == "search" else "out.gait")
    result = CliRunner().invoke(main, [*args, "-o", str(out)])
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith(f"error: {line}"), result.stderr
    assert result.stderr.count("\n") == 1
    assert not out.exists()


def test_a_missing_wave_option_is_a_usage_error(tmp_path):
    """A required option has no default: without -A the serpenoid is a usage error, not
    a gait of amplitude None."""
    out = tmp_path / "out.gait"
    args = ["gait", "serpenoid", "snake3", "-w", "0.3", "-d", "0.3", "--cycles", "1"]
    result = CliRunner().invoke(main, [*args, "-o", str(out)])
    assert result.exit_code == 2
    assert "Missing option '--amplitude'" in result.stderr
    assert not out.exists()
