"""`snakebot config` against the controller's real C device logic on a pty: every setting
listed with its unit, values read and written by name with units or value names, and
bad names or values refused (exit 2) before anything is written."""

from __future__ import annotations

import json

import pytest
from controller_cli_support import cli

from snakebot.link.controller import load
from snakebot.sim.controller_pty import ControllerPty


@pytest.fixture
def server():
    with ControllerPty() as s:
        yield s


def config(server, *args: str):
    return cli("config", "--port", server.device, *args)


def config_json(server, *args: str):
    result = config(server, *args, "--json")
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


def test_the_list_is_every_rw_setting_with_its_unit(server):
    rows = config_json(server)
    names = [r["name"] for r in rows]
    assert "Safe Action" in names and "Bus Loss Limit" in names and "Servo Error Mask" in names
    assert not any(n.startswith("Upload") for n in names)  # upload machinery, not settings
    table = load()
    for row in rows:
        reg = table.register(row["name"])
        assert reg.access == "RW"
        assert row["value"] == reg.default, row
        if reg.scale is not None:
            assert row["unit"] == reg.scale.unit
    by_name = {r["name"]: r for r in rows}
    assert by_name["Safe Action"]["meaning"] in table.enums["Safe Action"]
    assert by_name["Servo Error Mask"]["meaning"]  # the error bits in words
    text = config(server).stdout
    assert "Link Timeout" in text and " s)" in text


def test_set_with_a_unit_is_written_and_read_back(server):
    row = config_json(server, "set", "link-timeout", "1.5s")
    assert row["value"] == 15 and row["physical"] == 1.5 and row["unit"] == "s"
    assert config_json(server, "get", "LINK_TIMEOUT")["value"] == 15
    row = config_json(server, "set", "steering offset", "-10deg")
    assert row["value"] == round(-10 / (300 / 1023)) and row["physical"] < 0


def test_set_by_value_name(server):
    assert config_json(server, "set", "safe-action", "hold")["meaning"] == "HOLD"
    assert config_json(server, "get", "safe-action")["value"] == load().enums["Safe Action"]["HOLD"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("get", "safe-actoin"), "did you mean safe-action?"),
        (("set", "bus-loss", "3"), "did you mean bus-loss-limit?"),
        (("get", "upload-crc"), "no setting 'upload-crc'"),
        (("set", "speed-scale", "5x"), "Speed Scale takes 1-1024, not 1280"),
        (("set", "safe-action", "explode"), "one of HOLD, TORQUE_OFF"),
        (("set", "bus-loss-limit", "3 furlongs"), "has no unit: give its raw value"),
        (("set", "link-timeout", "soon"), "cannot read the value"),
        (("set", "bus-loss-limit"), "set takes NAME and VALUE"),
        (("get",), "get takes one NAME"),
    ],
)
def test_bad_names_and_values_change_nothing(server, args, message):
    before = config_json(server)
    result = config(server, *args)
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert config_json(server) == before


def test_help_explains_names_values_and_units():
    out = cli("config", "--help").stdout
    assert "set link-timeout 1.5s" in out and "value names" in out
