"""`snakebot bus read` decodes special values and `bus write` takes units, on sim://."""

from __future__ import annotations

import itertools
import json

import pytest
from click.testing import CliRunner

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli import main
from snakebot.facts import devices
from snakebot.sim.urlhandler.protocol_sim import forget_named_buses

AX12 = devices.ax12()
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
    [("goal-position", 30.0, "deg"), ("goal-position", 2.0, "rad"), ("moving-speed", 50.0, "rpm")],
)
def test_write_converts_units_through_the_description(port, register, amount, unit):
    result = bus("write", "1", register, f"{amount:g}{unit}", "--port", port, "--json")
    assert result.exit_code == 0, result.output
    name = json.loads(result.stdout)["register"]
    reg = AX12.register(name)
    value = registers(port, register)[name]["value"]
    assert value == reg.from_units(amount, unit)
    # within half a step of what was asked
    assert abs(reg.to_units(value, unit) - amount) <= reg.scale.factor_in(unit) / 2


@pytest.mark.parametrize(
    ("register", "value", "message"),
    [
        ("moving-speed", "0rpm", "0 means maximum speed"),
        ("moving-speed", "0.01rpm", "below one step"),
        ("moving-speed", "30deg", "Moving Speed is in rpm: cannot convert 'deg'"),
        ("led", "3deg", "LED has no unit"),
        ("goal-position", "1000deg", "Goal Position takes 0-1023"),
        ("goal-position", "fast", "cannot read the value 'fast'"),
    ],
)
def test_write_refuses_unit_mistakes_before_sending(port, register, value, message):
    result = bus("write", "1", register, value, "--port", port)
    assert result.exit_code == 2
    assert result.stderr.startswith("error: ") and message in result.stderr
    assert "Traceback" not in result.output
