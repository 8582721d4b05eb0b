"""The pieces behind `snakebot bus`: ID and baud lists, register names, value decoding."""

from __future__ import annotations

import pytest

from snakebot.formats.protocol import ControlTable
from snakebot.formats.register_values import (
    COMMON_BAUDS,
    BusCommandError,
    baud_from_register,
    baud_register,
    check_write,
    decode,
    describe_value,
    parse_bauds,
    parse_ids,
    resolve_register,
)

TABLE = ControlTable.for_model("AX-12A")


def test_parse_ids():
    assert parse_ids("0-253") == list(range(254))
    assert parse_ids("5-7, 1,6,2") == [5, 6, 7, 1, 2]
    for bad in ("254", "3-1", "a-b", "", "1-300"):
        with pytest.raises(BusCommandError):
            parse_ids(bad)


def test_parse_bauds():
    assert parse_bauds("1000000,57600") == [1_000_000, 57_600]
    assert parse_bauds("common") == list(COMMON_BAUDS)
    with pytest.raises(BusCommandError, match="cannot read the baud rates"):
        parse_bauds("fast")


def test_common_bauds_are_the_register_rates():
    for bps in COMMON_BAUDS:
        assert abs(baud_from_register(baud_register(bps)) - bps) < 1


def test_baud_register_formula_and_tolerance():
    assert baud_register(1_000_000) == 1
    assert baud_register(57_600) == 34  # 57142.9, 0.8 % off: within the UART margin
    assert baud_register(2_000_000) == 0
    with pytest.raises(BusCommandError, match="2000000 / \\(n \\+ 1\\)"):
        baud_register(300_000)
    with pytest.raises(BusCommandError):
        baud_register(5_000)  # below 2,000,000 / 255


def test_register_names_in_any_spelling_and_addresses():
    for text in ("Goal Position", "goal-position", "GOAL_POSITION", "goalposition", "30", "0x1e"):
        assert resolve_register(text).name == "Goal Position"
    with pytest.raises(BusCommandError, match="no AX-12A register starts at address 31"):
        resolve_register("31")  # the middle of Goal Position


def test_check_write_uses_the_table_ranges():
    check_write(TABLE.by_name("Temperature Limit"), 255)  # no documented range: the byte
    check_write(TABLE.by_name("Moving Speed"), 2047)
    with pytest.raises(BusCommandError, match="Moving Speed takes 0-2047, not 2048"):
        check_write(TABLE.by_name("Moving Speed"), 2048)
    with pytest.raises(BusCommandError, match="read-only"):
        check_write(TABLE.by_name("Moving"), 0)


def test_decode_scales_and_directions():
    load = decode(TABLE.by_name("Present Load"), 0x400 | 512)
    assert (load["direction"], load["magnitude"]) == ("CW", 512)
    assert load["physical"] == pytest.approx(50.0, abs=0.1)
    assert describe_value(load) == "1536 (512 CW, 50.05 % of stall torque)"
    # Moving Speed in joint mode has no direction bit.
    speed = decode(TABLE.by_name("Moving Speed"), 100)
    assert "direction" not in speed and speed["physical"] == pytest.approx(11.1)
    wheel = decode(TABLE.by_name("Moving Speed"), 0x400 | 100)
    assert wheel["direction"] == "CW"
    voltage = decode(TABLE.by_name("Present Voltage"), 121)
    assert describe_value(voltage) == "121 (12.1 V)"
    assert describe_value(decode(TABLE.by_name("LED"), 1)) == "1"
