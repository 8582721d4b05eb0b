"""`snakebot robot calibrate` against the emulated robot (sim://), whose servos start at
the zero ticks of the robot file it is given."""

from __future__ import annotations

import json
from importlib import resources

import pytest
import tomlkit
from click.testing import CliRunner

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli import main
from snakebot.facts import devices
from snakebot.link.bus.calibrate import JOG_DEG
from snakebot.model.robots import load_robot

pytestmark = [pytest.mark.timeout(120), pytest.mark.serial]  # real-time sim:// replies

ORIGINAL = resources.files("snakebot.model.robots").joinpath("snake5.toml").read_text()
REAL_ZEROS = [500, 521, 530, 547]  # where the emulated robot's servos really sit


def robot_files(tmp_path, zeros=REAL_ZEROS):
    """(the file to calibrate: snake5 as shipped, the sim:// port of a robot whose
    servos rest at ``zeros``)."""
    mine = tmp_path / "mine.toml"
    mine.write_text(ORIGINAL)
    doc = tomlkit.parse(ORIGINAL)
    for joint, zero in zip(doc["joints"], zeros, strict=True):
        joint["zero_tick"] = zero
        joint["min_deg"] = -20.0  # narrow, so that any zero here is a valid robot
    real = tmp_path / "real.toml"
    real.write_text(tomlkit.dumps(doc))
    return mine, f"sim://?robot={real}"


def calibrate(*args, input=None):
    return CliRunner().invoke(main, ["robot", "calibrate", *map(str, args)], input=input)


def comment_lines(text):
    return [line for line in text.splitlines() if "#" in line]


def test_yes_reads_zero_ticks_keeps_signs_and_comments(tmp_path):
    mine, port = robot_files(tmp_path)
    result = calibrate(mine, "--port", port, "--yes", "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    jog_ticks = round(JOG_DEG * devices.ax12().require_position().scale.per_unit("deg"))
    for joint, zero in zip(report["joints"], REAL_ZEROS, strict=True):
        assert joint["zero_tick"] == zero and joint["sign"] == 1
        assert joint["sign_from"] == "file"
        assert abs(joint["jog_moved_ticks"] - jog_ticks) <= 2  # the servo followed
    calibrated = load_robot(mine)
    assert [j.zero_tick for j in calibrated.joints] == REAL_ZEROS
    text = mine.read_text()
    assert comment_lines(text) == comment_lines(ORIGINAL)  # every comment kept, in place
    assert len(text.splitlines()) == len(ORIGINAL.splitlines())


def test_signs_come_from_the_user_after_each_jog(tmp_path):
    mine, port = robot_files(tmp_path)
    result = calibrate(mine, "--port", port, input="\ny\nn\ny\nn\n")
    assert result.exit_code == 0, result.output
    assert result.stdout.count("counter-clockwise, seen from above?") == 4
    assert [j.sign for j in load_robot(mine).joints] == [1, -1, 1, -1]
    assert [j.zero_tick for j in load_robot(mine).joints] == REAL_ZEROS


def test_a_missing_servo_leaves_the_file_alone(tmp_path):
    mine, _ = robot_files(tmp_path)
    result = calibrate(mine, "--port", "sim://?ids=10,11,15", "--yes")
    assert result.exit_code == 2
    assert "error: servo 16 of snake5 does not answer" in result.stderr
    assert mine.read_text() == ORIGINAL


def test_a_zero_that_makes_the_limits_impossible_is_not_written(tmp_path):
    # a horn mounted far off centre: -90 degrees from tick 100 is below tick 0
    mine, port = robot_files(tmp_path, zeros=[100, 512, 512, 512])
    result = calibrate(mine, "--port", port, "--yes")
    assert result.exit_code == 2
    assert result.stderr.startswith("error: ") and "Traceback" not in result.output
    assert "min_deg" in result.stderr and "could not open" not in result.stderr
    assert mine.read_text() == ORIGINAL
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".mine")]  # no temp left


def test_writing_the_calibration_keeps_the_files_mode(tmp_path):
    # It was made 0600 by the temporary file (issue #28).
    from snakebot.link.bus.calibrate import write_atomically

    path = tmp_path / "robot.toml"
    path.write_text("old\n")
    path.chmod(0o644)
    write_atomically(path, "new\n")
    assert path.read_text() == "new\n" and path.stat().st_mode & 0o777 == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["robot.toml"]
