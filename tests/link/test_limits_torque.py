"""A robot-wide torque limit (issue #17): `[limits] torque` in the robot file, validated
in the servo description's unit; `snakebot limits set ROBOT.toml` sends it, and the
controller (its C device logic behind a real pty, on an emulated bus of the robot's
AX-12s) holds every servo's Torque Limit to it, writing it again after a power cycle."""

from __future__ import annotations

import time
from importlib import resources
from pathlib import Path

import pytest
from controller_cli_support import cli, cli_json

from snakebot.core import lib
from snakebot.link.controller import load
from snakebot.model.robots import RobotError, load_robot, parse_robot
from snakebot.model.robots.model import TORQUE_LIMIT
from snakebot.sim.controller_pty import ControllerPty

pytestmark = pytest.mark.timeout(120)

CTL = load()
SNAKE5 = resources.files("snakebot.model.robots").joinpath("snake5.toml").read_text()


def with_torque(value: str) -> str:
    return SNAKE5 + f"\n[limits]\ntorque = {value}\n"


def robot_file(tmp_path: Path, value: str) -> Path:
    path = tmp_path / "snake5-torque.toml"
    path.write_text(with_torque(value))
    return path


@pytest.mark.parametrize("value", ['"60%"', "60", '" 60 % "', "60.0"])
def test_the_torque_limit_is_a_percentage_of_stall_torque(value):
    robot = parse_robot(with_torque(value))
    assert robot.torque_limit == TORQUE_LIMIT.from_units(60.0)
    assert robot.torque_limit_percent == pytest.approx(60.0, abs=0.1)


def test_a_robot_without_one_leaves_the_servos_their_own():
    assert load_robot("snake5").torque_limit is None
    assert parse_robot(with_torque('"100%"')).torque_limit == TORQUE_LIMIT.value_range()[1]


@pytest.mark.parametrize(
    ("value", "says"),
    [
        ('"0%"', "above 0"),
        ("0", "above 0"),
        ('"150%"', "at most 100%"),
        ("-5", "above 0"),
        ('"60 percent"', 'a percentage such as "60%"'),
        ("true", "must be"),
        ("nan", "finite"),
    ],
)
def test_a_bad_torque_limit_is_refused_naming_key_and_line(value, says):
    with pytest.raises(RobotError) as err:
        parse_robot(with_torque(value), "r.toml")
    message = str(err.value)
    line = SNAKE5.count("\n") + 3  # the `torque =` line after the appended [limits]
    assert message.startswith(f"r.toml, line {line}: key 'limits.torque'")
    assert says in message and "\n" not in message


def test_a_misspelt_limits_key_is_refused():
    with pytest.raises(RobotError, match="did you mean 'torque'"):
        parse_robot(SNAKE5 + '\n[limits]\ntorqe = "60%"\n')


def test_limits_set_with_a_bad_torque_limit_ends_in_one_line_before_any_port(tmp_path):
    result = cli("limits", "set", robot_file(tmp_path, '"150%"'), "--port", "/nonexistent")
    assert result.exit_code == 2, result.output
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "limits.torque" in lines[0]


def torque_held(server: ControllerPty, ids: tuple[int, ...]) -> list[int]:
    assert server.bus is not None
    with server.lock:
        return [server.bus.servo(i).regs.get("Torque Limit") for i in ids]


def test_limits_set_sends_the_torque_limit_and_the_servos_hold_it(tmp_path):
    robot = load_robot(robot_file(tmp_path, '"60%"'))
    raw = TORQUE_LIMIT.from_units(60.0)
    with ControllerPty(robot="snake5") as server:
        assert server.bus is not None
        assert torque_held(server, robot.servo_ids) == [TORQUE_LIMIT.default] * robot.n_joints
        shown = cli_json("limits", "show", "--port", server.device)
        assert (shown["count"], shown["torque_limit"], shown["torque_limit_percent"]) == (
            0,
            None,
            None,
        )
        report = cli_json("limits", "set", robot_file(tmp_path, '"60%"'), "--port", server.device)
        assert (report["state"], report["count"]) == ("VERIFIED", robot.n_joints)
        assert report["torque_limit"] == raw
        assert report["torque_limit_percent"] == pytest.approx(60.0, abs=0.1)
        assert torque_held(server, robot.servo_ids) == [raw] * robot.n_joints
        shown = cli_json("limits", "show", "--port", server.device)
        assert (shown["state"], shown["torque_limit"]) == ("VERIFIED", raw)
        assert shown["torque_limit_percent"] == pytest.approx(60.0, abs=0.1)

        # a servo's power cycle sets its Torque Limit back to Max Torque: the controller's
        # audit finds it and writes it again, with no help from the host
        sid = robot.servo_ids[1]
        with server.lock:
            servo = server.bus.servo(sid)
            servo.power_off(servo.t)
            servo.power_on(servo.t)
            assert servo.regs.get("Torque Limit") == servo.regs.get("Max Torque")
        deadline = time.monotonic() + 30
        while torque_held(server, robot.servo_ids) != [raw] * robot.n_joints:
            assert time.monotonic() < deadline, torque_held(server, robot.servo_ids)
            time.sleep(0.05)

        text = cli("limits", "set", robot_file(tmp_path, '"60%"'), "--port", server.device)
        assert text.exit_code == 0, text.output
        assert "torque limit 60% of stall torque" in text.stdout
        assert "angle and torque limits are VERIFIED" in text.stdout

        shown = cli("limits", "show", "--port", server.device)
        assert "torque limit 60% of stall torque" in shown.stdout
        assert "angle and torque limits are VERIFIED" in shown.stdout


def test_none_on_the_limits_page_is_the_firmware_none():
    """The Limits page's Robot Torque Limit says "none" with the value the bus master
    uses for none, which no servo takes as a Torque Limit."""
    none = CTL.register("Robot Torque Limit").default
    assert none == lib.BUS_TORQUE_LIMIT_NONE
    assert not TORQUE_LIMIT.accepts(none)
