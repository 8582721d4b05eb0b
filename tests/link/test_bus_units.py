"""`snakebot bus read` decodes special values and `bus write` takes units, on sim://."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli import main
from snakebot.facts import devices
from snakebot.model import robots
from snakebot.sim.urlhandler.protocol_sim import forget_named_buses

AX12 = devices.ax12()
ROBOT_FILE = Path(robots.__file__).with_name("snake5.toml")
_names = itertools.count()


@pytest.fixture()
def port():
    yield f"sim://units{next(_names)}?ids=1"
    forget_named_buses()


def bus(*args: str):
    return CliRunner().invoke(main, ["bus", *args])


def registers(port: str, *names: str) -> dict[str, dict]:
    result = bus("read", "1", *names, "--port", port, "--json")
    assert result.exit_code == 0, result.output
    return {r["name"]: r for r in json.loads(result.stdout)["registers"]}


def test_read_says_what_special_values_mean(port):
    values = registers(port, "baud-rate", "alarm-led", "moving-speed")
    factory_baud = AX12.register("Baud Rate").default
    assert values["Baud Rate"]["meaning"] == f"{AX12.require_baud().rate(factory_baud):.0f} bit/s"
    assert values["Alarm LED"]["meaning"] == "overheating, overload"  # factory mask 36
    assert values["Moving Speed"]["value"] == 0
    assert "maximum" in values["Moving Speed"]["meaning"]
    text = bus("read", "1", "moving-speed", "--port", port).stdout
    assert "0 (maximum speed: no speed control)" in text


@pytest.mark.parametrize(
    ("register", "amount", "unit"),
    [
        ("goal-position", 150.0, "absdeg"),
        ("goal-position", 250.0, "absdeg"),
        ("moving-speed", 50.0, "rpm"),
    ],
)
def test_write_converts_units_through_the_description(port, register, amount, unit):
    result = bus("write", "1", register, f"{amount:g}{unit}", "--port", port, "--json")
    assert result.exit_code == 0, result.output
    name = json.loads(result.stdout)["register"]
    reg = AX12.register(name)
    value = registers(port, register)[name]["value"]
    unit = {"absdeg": "deg"}.get(unit, unit)  # the servo's own 0-300 dial is its scale
    assert value == reg.from_units(amount, unit)
    # within half a step of what was asked
    assert abs(reg.to_units(value, unit) - amount) <= reg.scale.factor_in(unit) / 2


@pytest.mark.parametrize(("amount", "unit"), [(30.0, "deg"), (-30.0, "deg"), (0.5, "rad")])
def test_an_angle_is_from_the_servos_centre(port, amount, unit):
    """30deg is 30 degrees from tick 512, as a joint angle is read, not 30 degrees of the
    servo's 0-300 dial (tick 102, 120 degrees off centre)."""
    result = bus("write", "1", "goal-position", f"{amount:g}{unit}", "--port", port)
    assert result.exit_code == 0, result.output
    reg = AX12.register("Goal Position")
    centre = AX12.require_position().centre
    value = registers(port, "goal-position")["Goal Position"]["value"]
    assert abs(reg.to_units(value - centre, unit) - amount) <= reg.scale.factor_in(unit) / 2
    read = registers(port, "goal-position")["Goal Position"]
    assert read["from_centre_deg"] == pytest.approx(reg.to_units(value - centre, "deg"), abs=0.1)


def test_with_a_robot_an_angle_is_the_joints(tmp_path):
    """--robot: the joint's zero tick and sign apply, and its limits are enforced."""
    robot = tmp_path / "r.toml"
    text = ROBOT_FILE.read_text()
    robot.write_text(
        text.replace("sign = 1", "sign = -1", 1).replace("zero_tick = 512", "zero_tick = 500", 1)
    )
    port = "sim://?robot=snake5&ideal=1"
    result = bus(
        "write", "10", "goal-position", "30deg", "--robot", str(robot), "--port", port, "--json"
    )
    assert result.exit_code == 0, result.output
    written = json.loads(result.stdout)
    assert written["value"] == 500 - round(
        30 / AX12.register("Goal Position").scale.factor_in("deg")
    )
    assert written["joint"] == "phi1" and written["joint_deg"] == 29.9  # the nearest tick's
    text = bus("write", "10", "goal-position", "30deg", "--robot", str(robot), "--port", port)
    # tick 398 is 33.4 deg from the servo's centre (512) but 29.9 from the joint's zero (500)
    assert "-33.4 deg from the centre" in text.stdout and "; joint phi1 +29.9 deg" in text.stdout
    refused = bus("write", "10", "goal-position", "100deg", "--robot", str(robot), "--port", port)
    assert refused.exit_code == 2
    assert "outside joint phi1's limits (-90 to 90 deg)" in refused.stderr


@pytest.mark.parametrize(
    ("register", "value", "message"),
    [
        ("moving-speed", "0rpm", "0 means maximum speed"),
        ("moving-speed", "0.01rpm", "below one step"),
        ("moving-speed", "30deg", "Moving Speed is in rpm: cannot convert 'deg'"),
        ("led", "3deg", "LED has no unit"),
        ("goal-position", "1000deg", "outside Goal Position's travel"),
        ("goal-position", "fast", "cannot read the value 'fast'"),
    ],
)
def test_write_refuses_unit_mistakes_before_sending(port, register, value, message):
    result = bus("write", "1", register, value, "--port", port)
    assert result.exit_code == 2
    assert result.stderr.startswith("error: ") and message in result.stderr
    assert "Traceback" not in result.output
