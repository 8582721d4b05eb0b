"""The device descriptions (snakebot.facts.devices): every file loads, variants inherit, and
registers convert between raw values and units as the servos do."""

from __future__ import annotations

import functools
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from snakebot.facts import devices
from snakebot.facts.devices import DeviceError, Encoding, loader

AX = devices.ax12()
CTL = devices.controller()


def test_every_described_device_loads():
    assert set(devices.names()) == {"AX-12A", "AX-12W", "AX-18A", "MX-28", "MX-64", "controller"}
    assert devices.names("controller") == ("controller",)
    for name in devices.names():
        device = devices.load(name)
        assert device.protocol == "1.0"
        assert device.register("Model Number").default == device.model_number
        assert device.default_image()[0:2] == device.model_number.to_bytes(2, "little")


def test_ax12_position_facts():
    position = AX.require_position()
    assert position.range == (0, 1023) and position.centre == 512
    assert position.span_deg == pytest.approx(300.0)
    goal = AX.register("Goal Position")
    assert goal.to_units(1023, "deg") == pytest.approx(300.0)
    middle = math.radians(position.span_deg / 2)  # the centre tick is the nearest to it
    assert goal.to_units(position.centre, "rad") == pytest.approx(middle, abs=position.rad_per_tick)
    assert position.ticks_per_rad == pytest.approx(1 / position.rad_per_tick)
    assert goal.from_units(goal.to_units(position.centre, "rad"), "rad") == position.centre


def test_mx_position_covers_a_turn_in_4096_steps():
    mx = devices.load("MX-28").require_position()
    assert mx.range == (0, 4095) and mx.centre == 2048
    assert mx.ticks_per_rad * 2 * math.pi == pytest.approx(4096)


def test_sign_magnitude_speeds_are_negative_clockwise():
    speed = AX.register("Present Speed")
    assert speed.encoding is Encoding.SIGN_MAGNITUDE_BIT10
    assert speed.value(100) == 100 and speed.value(1024 + 100) == -100
    assert speed.to_units(1024 + 100, "rpm") == pytest.approx(-11.1)
    assert speed.from_units(-11.1, "rpm") == 1024 + 100
    assert speed.to_units(100, "rad/s") == pytest.approx(11.1 * 2 * math.pi / 60)


@given(st.integers(0, 2047))
def test_sign_magnitude_round_trips(raw):
    enc = Encoding.SIGN_MAGNITUDE_BIT10
    if raw != 1024:  # "minus zero" reads as 0 and is written back as plain 0
        assert enc.encode_value(enc.decode_value(raw)) == raw


def test_twos_complement_registers():
    steer = CTL.register("Steering Offset")
    assert steer.signed and steer.encode(-3) == b"\xfd\xff" and steer.decode(b"\xfd\xff") == -3
    # the controller speaks in its servos' units
    assert steer.scale == AX.scale("position")
    with pytest.raises(DeviceError, match="takes -512..512"):
        steer.encode(600)


def test_baud_formulas():
    ax = AX.require_baud()
    assert ax.rate(1) == 1_000_000 and ax.rate(34) == pytest.approx(57142.86, abs=0.01)
    # within the UART's tolerance (the manuals' 3 %), the nearest rate
    assert ax.value_for(57600) == 34 and ax.value_for(300_000) is None
    assert ax.value_for(57600, tolerance=0.005) is None
    with pytest.raises(DeviceError, match="0..254"):
        ax.rate(255)
    mx = devices.load("MX-28").require_baud()
    assert [mx.rate(n) for n in (249, 250, 251, 252)] == [8000, 2_250_000, 2_500_000, 3_000_000]
    assert mx.value_for(3_000_000, 0.01) == 252
    with pytest.raises(DeviceError, match="fixed"):
        CTL.require_baud()


def test_status_return_level_is_a_device_fact():
    assert AX.status_return_level_address == AX.register("Status Return Level").address
    assert CTL.status_return_level_address == CTL.register("Status Return Level").address
    assert AX.status_return_level_address != CTL.status_return_level_address
    # the controller's byte at the servo's address means something else entirely
    assert CTL.covering(AX.status_return_level_address).name != "Status Return Level"


def test_variants_inherit_and_override():
    w = devices.load("ax-12w")
    assert w.based_on == "AX-12A" and w.model_number != AX.model_number
    differ = {a.name for a, b in zip(AX, w, strict=True) if a != b}
    assert differ == {
        "Model Number",
        "CW Compliance Margin",
        "CCW Compliance Margin",
        "CW Compliance Slope",
        "CCW Compliance Slope",
    }
    mx28, mx64 = devices.load("MX-28"), devices.load("MX-64")
    extra = {r.name for r in mx64} - {r.name for r in mx28}
    assert extra == {"Current", "Torque Control Mode Enable", "Goal Torque"}
    assert mx64.scale("speed") == mx28.scale("speed") != AX.scale("speed")
    assert devices.by_model_number(mx64.model_number) is mx64


def test_unknown_names_say_what_exists():
    with pytest.raises(DeviceError, match="AX-12A, AX-12W"):
        devices.load("XL-320")
    with pytest.raises(DeviceError, match="Goal Position"):
        AX.register("Goal")
    with pytest.raises(DeviceError, match="12 \\(AX-12A\\)"):
        devices.by_model_number(9999)
    with pytest.raises(DeviceError, match="no unit"):
        AX.register("LED").to_units(1)


def _with_files(monkeypatch, docs: dict) -> None:
    monkeypatch.setattr(
        loader, "_documents", lambda: {n: (f"{n}.json", d) for n, d in docs.items()}
    )
    # A cache of its own: the shipped devices' cache comes back untouched afterwards, so
    # what other modules cached from it (ControlTable's devices) stays the same objects.
    monkeypatch.setattr(loader, "_build", functools.cache(loader._build.__wrapped__))


@pytest.fixture
def broken(monkeypatch):
    """Load from the documents a test hands in, then restore the shipped ones."""
    return lambda docs: _with_files(monkeypatch, docs)


def _doc(registers, **extra):
    return {
        "schema": 1,
        "name": "X",
        "kind": "servo",
        "protocol": "1.0",
        "model_number": 1,
        "table_size": 8,
        "registers": [
            {"address": 0, "size": 2, "name": "Model Number", "access": "R"},
            *registers,
        ],
        **extra,
    }


@pytest.mark.parametrize(
    ("registers", "extra", "problem"),
    [
        ([{"address": 1, "size": 1, "name": "A", "access": "R"}], {}, "overlaps"),
        ([{"address": 7, "size": 2, "name": "A", "access": "R"}], {}, "does not fit"),
        ([{"address": 2, "size": 1, "name": "A", "access": "RW", "scale": "speed"}], {}, "speed"),
        ([{"address": 2, "size": 1, "name": "A", "access": "RW", "max": 3, "default": 4}], {}, "4"),
        ([{"address": 2, "size": 1, "name": "A", "access": "R", "encoding": "bcd"}], {}, "bcd"),
        ([{"address": 2, "size": 1, "name": "A", "access": "R", "read": [0, 256]}], {}, "0..255"),
        ([{"address": 2, "size": 1, "name": "A", "access": "R", "read": [5, 4]}], {}, "fit"),
        ([{"address": 2, "size": 1, "name": "A", "access": "R", "read": "B"}], {}, "low, high"),
        ([], {"status_return_level": "Status Return Level"}, "no register"),
        (
            [{"address": 2, "size": 2, "name": "G", "access": "RW", "min": 0, "max": 10}],
            {"position": {"register": "G", "centre": 5}},
            "a scale",
        ),
        (
            [
                {
                    "address": 2,
                    "size": 2,
                    "name": "G",
                    "access": "RW",
                    "min": 0,
                    "max": 10,
                    "scale": {"unit": "deg", "factor": 1},
                }
            ],
            {"position": {"register": "G", "centre": 11}},
            "centre in its range",
        ),
    ],
)
def test_broken_descriptions_are_refused(broken, registers, extra, problem):
    broken({"X": _doc(registers, **extra)})
    with pytest.raises(DeviceError, match=problem):
        devices.load("X")


def test_spans_cover_consecutive_registers():
    goal, speed = AX.register("Goal Position"), AX.register("Moving Speed")
    assert AX.span("Goal Position", "Moving Speed") == (goal.address, goal.size + speed.size)
    first, length = AX.span("Present Position", "Present Temperature")
    assert AX.covering(first + length - 1).name == "Present Temperature"
    with pytest.raises(DeviceError, match="does not come after"):
        AX.span("Present Speed", "Present Position")


def test_the_servo_window_speaks_in_the_servos_ticks_and_units():
    fields = {f.name: f for f in CTL.servo_window.fields}
    position = AX.require_position()
    assert fields["Zero Tick"].default == position.centre
    assert (fields["Min Tick"].default, fields["Max Tick"].default) == position.range
    assert fields["Max Tick"].value_range() == position.range
    assert fields["Present Speed"].encoding is AX.register("Present Speed").encoding
    assert fields["Present Load"].scale == AX.register("Present Load").scale


def test_values_read_have_the_range_the_servo_can_hold():
    """A read-only register's range comes from its ``read`` entry, written once (Present
    Position shares Goal Position's), or from its encoding; Model Number and Firmware
    Version have none (the model number is what identifies an unknown servo)."""
    ranges = {r.name: r.read_range() for r in AX.registers}
    assert ranges["Present Position"] == AX.register("Goal Position").value_range()
    assert ranges["Present Voltage"] == AX.register("Min Voltage Limit").value_range()
    assert ranges["Present Speed"] == ranges["Present Load"] == (0, 2047)
    assert ranges["Moving"] == ranges["Registered"] == (0, 1)
    assert ranges["Model Number"] is None and ranges["Firmware Version"] is None
    mx = devices.load("MX-64")  # a variant inherits them, in its own position range
    assert mx.register("Present Position").read_range() == (0, 4095)
