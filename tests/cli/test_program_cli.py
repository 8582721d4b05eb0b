"""`snakebot program build/show`: a spec in SI units becomes a program the controller's
own check accepts, and a bad spec is one line naming the problem, exit 2, nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.formats.gaittable import GaitTable, write_gait
from snakebot.formats.program import PeriodicSegment, SerpenoidSegment, TableSegment
from snakebot.formats.program.files import read_program
from snakebot.model.program_goals import predict
from snakebot.model.robots import load_robot

SNAKE5 = load_robot("snake5")
SPEC = """
robot = "snake5"
period_ms = 20
table = "walk.gait"
[[segment]]
kind = "periodic"
omega = 3.0
sin = [0.2, 0.2, 0.2, 0.2]
rate = [0.05, 0.0, 0.0, -0.05]
duration = 1.0
[[segment]]
kind = "serpenoid"
amplitude = 0.4
omega = 3.0
delta = 1.0
duration = 2.0
[[segment]]
kind = "table"
repetitions = 2
"""


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def write_spec(tmp_path: Path, text: str = SPEC) -> Path:
    frames = np.array([[j.zero_tick + 10 * k for j in SNAKE5.joints] for k in range(5)])
    table = GaitTable(SNAKE5.servo_ids, 20, True, SNAKE5.tick_limits, frames)
    write_gait(tmp_path / "walk.gait", table)
    spec = tmp_path / "plan.toml"
    spec.write_text(text)
    return spec


def test_build_writes_the_program_the_spec_describes(tmp_path: Path) -> None:
    spec = write_spec(tmp_path)
    out = tmp_path / "plan.prog"
    result = run("program", "build", str(spec), "-o", str(out), "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    prog = read_program(out)
    assert summary["bytes"] == out.stat().st_size == len(prog.encode())
    assert [type(s) for s in prog.segments] == [PeriodicSegment, SerpenoidSegment, TableSegment]
    assert prog.segments[1] == SerpenoidSegment(400, 3000, 1000, 0, 100)
    assert prog.segments[2] == TableSegment(0, 5, 2)
    assert prog.blocks[0][0] == (50, 200, 0) and prog.blocks[0][3] == (-50, 200, 0)
    assert [j.servo_id for j in prog.joints] == list(SNAKE5.servo_ids)
    assert prog.total_steps == 50 + 100 + 10
    # the first step of the serpenoid continues from where the periodic block was heading
    steps = np.abs(np.diff(predict(prog), axis=0))
    assert (steps[49] <= steps[40:49].max(axis=0) + 1).all()
    shown = run("program", "show", str(out), "--json")
    assert shown.exit_code == 0
    assert json.loads(shown.output)["segments"][1]["amplitude"] == 0.4
    text = run("program", "show", str(out))
    assert "serpenoid: amplitude 0.4" in text.output


def test_bad_specs_fail_in_one_line_with_exit_2_and_write_nothing(tmp_path: Path) -> None:
    out = tmp_path / "x.prog"
    cases = {
        "amplitude = 0.4": ("amplitude = 2.5", "segment 2: a segment's goals leave"),
        "omega = 3.0\ndelta": ("omega = 30.0\ndelta", "segment 2: a segment moves a joint faster"),
        'kind = "table"': ('kind = "tabel"', "segment 3: `kind` must be one of"),
        "repetitions = 2": ("repetitions = -1", "`repetitions` must be a whole number"),
        "duration = 2.0": ("duration = 9999.0", "`duration` = 9999 s is 499950 steps"),
        "period_ms = 20": ("period_ms = 25", "has a frame every 20 ms, the program a step"),
    }
    for before, (after, message) in cases.items():
        spec = write_spec(tmp_path, SPEC.replace(before, after, 1))
        result = run("program", "build", str(spec), "-o", str(out))
        assert result.exit_code == 2, (after, result.output)
        lines = result.output.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], lines
        assert not out.exists()
    not_toml = write_spec(tmp_path, "robot = ")
    assert run("program", "build", str(not_toml), "-o", str(out)).exit_code == 2
    gait = tmp_path / "walk.gait"
    result = run("program", "show", str(gait))
    assert result.exit_code == 2 and "not a program" in result.output
