"""`snakebot sim predict FILE.prog`: the pose a program takes the robot to, predicted from
the host's reference of the controller's generators and integrated as a table's frames;
on ideal servos the controller's own player (the C core, program mode) lands there too;
a bad program file is one line, exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.core import ffi, lib
from snakebot.formats.program import PeriodicSegment, Program, SerpenoidSegment
from snakebot.formats.program.files import write_program
from snakebot.model.gait.common import table_motion
from snakebot.model.program_spec import joints_of
from snakebot.model.robots import TICKS_PER_RAD, load_robot

TRIDENT = load_robot("trident")
SNAKE5 = load_robot("snake5")


def c_ticks(program: Program) -> np.ndarray:
    """The goals the C core sends at every step of the program (prog_goals/prog_advance)."""
    blob = program.encode()
    cursor = ffi.new("prog_cursor *")
    goals = ffi.new(f"uint16_t[{program.joint_count}]")
    lib.prog_start(cursor)
    out = []
    for _ in range(program.total_steps):
        lib.prog_goals(blob, cursor, 0, goals)
        out.append(list(goals))
        lib.prog_advance(blob, cursor, 1)
    return np.array(out)


def trident_program() -> Program:
    """Two periodic segments (a loop of the three arms, then the same loop the other way
    round) and a serpenoid-shaped wave: the carry joins them."""
    block = ((0, 300, 0), (0, 0, 300), (60, -300, 0))
    return Program(
        10,
        joints_of(TRIDENT),
        (
            PeriodicSegment(0, 3140, 400),
            SerpenoidSegment(200, -3140, 1000, 0, 200),
            PeriodicSegment(1, 3140, 200),
        ),
        (block, tuple((-r, -a, b) for r, a, b in block)),
    )


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def predict_json(path: Path, *extra: str) -> dict:
    result = run("sim", "predict", str(path), "--json", *extra)
    assert result.exit_code == 0, result.output
    return json.loads(result.output)


def test_prediction_integrates_the_goals_the_controller_sends(tmp_path: Path) -> None:
    program = trident_program()
    path = tmp_path / "loops.prog"
    write_program(path, program)
    summary = predict_json(path, "--ideal")
    assert summary["robot"] == "trident"  # found from the program's joints
    assert summary["frames"] == program.total_steps
    # the C core's own goals, integrated independently, land where the prediction says
    played = table_motion(TRIDENT, TRIDENT.ticks_to_angles(c_ticks(program)), 0.01, False)
    end = played.trajectory.q[-1, :3] - played.trajectory.q[0, :3]
    predicted = summary["predicted"]
    assert abs(predicted["dx"]) + abs(predicted["dy"]) > 0.05  # it does move the body
    assert np.allclose([predicted["dx"], predicted["dy"]], end[:2], atol=2e-3)
    assert predicted["dtheta"] == pytest.approx(end[2], abs=5e-3)
    # the controller's player on ideal servos: the same path, off by a goal's rounding
    difference = summary["difference"]
    assert difference["joint_max_rad"] <= 1.01 / TICKS_PER_RAD
    assert abs(difference["dx"]) < 2e-3 and abs(difference["dy"]) < 2e-3
    assert abs(difference["dtheta"]) < 5e-3


def test_modelled_servos_lag_the_program(tmp_path: Path) -> None:
    path = tmp_path / "loops.prog"
    write_program(path, trident_program())
    summary = predict_json(path)
    assert summary["servos"] == TRIDENT.servo_model
    assert summary["difference"]["joint_max_rad"] > 0.005  # the servos lag a moving goal
    assert "program" in summary["predicted"]["source"]


def test_text_report_counts_program_steps(tmp_path: Path) -> None:
    path = tmp_path / "loops.prog"
    write_program(path, trident_program())
    result = run("sim", "predict", str(path), "--ideal")
    assert result.exit_code == 0, result.output
    assert "800 program steps every 10 ms" in result.output


@pytest.mark.parametrize(
    ("data", "words"),
    [
        (b"SNKP\x01", "truncated"),
        (None, "CRC-32"),  # a real program with one byte changed
    ],
)
def test_a_bad_program_file_is_one_line(tmp_path: Path, data: bytes | None, words: str) -> None:
    path = tmp_path / "bad.prog"
    if data is None:
        blob = bytearray(trident_program().encode())
        blob[-1] ^= 0x55
        data = bytes(blob)
    path.write_bytes(data)
    result = run("sim", "predict", str(path))
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and words in lines[0]


def test_a_program_for_other_joints_names_the_robot(tmp_path: Path) -> None:
    path = tmp_path / "loops.prog"
    write_program(path, trident_program())
    result = run("sim", "predict", str(path), "--robot", "snake5")
    assert result.exit_code == 2
    assert result.output.startswith("error: ") and "--robot" in result.output
    assert len(result.output.strip().splitlines()) == 1
