"""A newcomer's first hour, as the README and the help texts lead it: a command that needs
an optional package says so before it does any work; a bare number given for an angle is
explained when it breaks a limit; every distance printed carries its unit."""

from __future__ import annotations

import json
import re
import sys

import pytest
from click.testing import CliRunner

from snakebot.cli import main

SEARCH = ["gait", "search", "snake5", "--param", "A=10deg:50deg:2"]
SEARCH += ["--param", "delta=30deg:150deg:2", "--param", "omega=360deg", "--workers", "1"]


@pytest.mark.parametrize(
    ("missing", "args", "install"),
    [
        ("pyarrow", [*SEARCH, "-o", "runs.parquet"], "snakebot[search]"),
        ("cma", [*SEARCH[:3], "--param", "A=10deg:50deg", "--method", "cma"], "snakebot[search]"),
        ("matplotlib", [*SEARCH, "--plot", "runs.png"], "snakebot[plot]"),
        ("matplotlib", ["gait", "show", "GAIT", "--plot", "s.png"], "snakebot[plot]"),
        ("scipy", ["plan", "trident", "--to", "2,1,30deg", "-o", "go.gait"], "snakebot[plan]"),
        ("scipy", ["sim", "goto", "trident", "--to", "2,1,30deg"], "snakebot[plan]"),
        ("mujoco", ["sim", "friction", "GAIT"], "snakebot[physics]"),
        ("mujoco", ["demo"], "snakebot[physics]"),
        ("unicorn", ["demo", "--world", "kinematic"], "snakebot[mcu]"),  # the default board
        ("unicorn", ["sim", "serve"], "snakebot[mcu]"),
        *(
            ("foxglove", [*command, "--foxglove", "8765"], "snakebot[live]")
            for command in (
                ["sim", "serve"],
                ["monitor", "--port", "/dev/ttySNAKEBOT-missing"],
                ["drive", "--port", "/dev/ttySNAKEBOT-missing", "--keys", "q"],
                ["bus", "play", "GAIT", "--port", "sim://?robot=snake5"],
            )
        ),
    ],
)
def test_a_missing_extra_stops_the_command_before_it_works(
    tmp_path, monkeypatch, missing, args, install
):
    gait = tmp_path / "s.gait"
    made = CliRunner().invoke(
        main,
        ["gait", "serpenoid", "snake5", "-A", "20deg", "-w", "180deg", "-d", "60deg"]
        + ["--cycles", "1", "-o", str(gait)],
    )
    assert made.exit_code == 0, made.output
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, missing, None)  # as if it were not installed
    result = CliRunner().invoke(main, [str(gait) if a == "GAIT" else a for a in args])
    assert result.exit_code == 2, result.output
    assert f"needs {missing}, which is not installed: pip install '{install}'" in result.stderr
    assert result.stdout == ""  # nothing was started: no progress, no results
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.gait", "s.gait.json"]


def test_a_bare_number_for_an_angle_is_explained_when_it_breaks_a_limit(tmp_path):
    result = CliRunner().invoke(
        main,
        ["gait", "serpenoid", "snake5", "-A", "30", "-w", "180deg", "-d", "60deg"]
        + ["--cycles", "1", "-o", str(tmp_path / "s.gait")],
    )
    assert result.exit_code == 2
    assert "-A 30 is in radians" in result.stderr
    assert "a number without a unit is radians; for degrees write -A 30deg" in result.stderr


def test_distances_are_printed_with_their_unit(tmp_path):
    runner = CliRunner()
    gait = str(tmp_path / "s.gait")
    made = runner.invoke(
        main,
        ["gait", "serpenoid", "snake5", "-A", "20deg", "-w", "180deg", "-d", "60deg"]
        + ["--cycles", "1", "-o", gait],
    )
    assert "dx = " in made.stdout and " m  dy = " in made.stdout  # snake5 is in metres
    shown = runner.invoke(main, ["gait", "show", gait])  # the same unit, read from FILE.json
    assert " m  dy = " in shown.stdout and " u " not in shown.stdout, shown.output
    predicted = runner.invoke(main, ["sim", "predict", gait])
    assert predicted.exit_code == 0, predicted.output
    assert "m in position" in predicted.stdout and " m/s sideways" in predicted.stdout
    plan = runner.invoke(
        main, ["plan", "trident", "--to", "2,1,30deg", "-o", str(tmp_path / "go.gait"), "--json"]
    )
    assert plan.exit_code == 0, plan.output
    summary = json.loads(plan.stdout)
    # the trident is dimensionless: its unit is named and related to metres
    assert summary["length_unit"] == "u"
    assert "1 u = 0.1 m" in summary["length_legend"]
    shown = runner.invoke(
        main, ["plan", "trident", "--to", "2,1,30deg", "-o", str(tmp_path / "g.gait")]
    )
    assert " u  y = " in shown.stdout and "1 u = 0.1 m" in shown.stdout
    shown = runner.invoke(main, ["gait", "show", str(tmp_path / "g.gait")])
    assert " u  dy = " in shown.stdout and "1 u = 0.1 m" in shown.stdout, shown.output
    program = runner.invoke(
        main, ["plan", "trident", "--to", "0.3,0.1,20deg", "-o", str(tmp_path / "go.prog")]
    )
    counts = re.findall(r"\((\d+) (steps?)\)", program.stdout)
    assert counts and all((n == "1") == (word == "step") for n, word in counts), program.output
