"""Window pages: register 126 (Window Page) selects what addresses 127..252 show, the
servo records on pages 0..2, the pages described in controller.json beyond them."""

from __future__ import annotations

import pytest
from ctl_support import CTL, CTL_ID, Device, lib_value

from snakebot.core import lib
from snakebot.facts.devices import DeviceError
from snakebot.formats.protocol import ErrorFlags, write
from snakebot.link.controller import ControllerErrors, load

PROGRAM = CTL.page("Program")
SELECTOR = CTL.register("Window Page")


@pytest.fixture
def dev() -> Device:
    return Device()


def page_values(dev: Device, page) -> dict[str, int]:
    assert dev.set("Window Page", page.number) == 0
    return {f.name: dev.get(f.name) for f in page.fields}


def test_the_program_page_reports_capacity_and_segments(dev):
    values = page_values(dev, PROGRAM)
    assert values["Table Capacity"] == CTL.limits["max_table_bytes"]
    assert values["Max Segments"] == CTL.limits["max_program_segments"] >= 64
    assert values["Refusal Reason"] == lib_value("Refusal Reason", "NONE")
    # page 0 still shows the servo records at the same addresses
    assert dev.set("Window Page", 0) == 0
    assert dev.servo_window(0)[0]["Zero Tick"] == CTL.servo_field("Zero Tick").default


def test_a_board_capacity_is_shown_and_enforced(dev):
    lib.ctl_set_capacity(dev.d, 1000)
    assert page_values(dev, PROGRAM)["Table Capacity"] == 1000
    offset = CTL.register("Upload Offset")
    data = offset.encode(1000 - 8) + bytes(9)  # one byte past the capacity
    assert dev.one(write(CTL_ID, offset.address, data)).error == ErrorFlags.RANGE
    assert dev.flags & ControllerErrors.UPLOAD_LENGTH
    assert dev.one(write(CTL_ID, offset.address, data[:-1])).error == 0
    # a commit longer than the capacity is refused even when the bytes are staged
    lib.ctl_set_capacity(dev.d, 500)
    assert dev.commit(1000, 0) == 0
    assert dev.get("Upload Result") == lib_value("Upload Result", "BAD_LENGTH")
    # the core never accepts more than its buffers hold
    lib.ctl_set_capacity(dev.d, 65535)
    assert page_values(dev, PROGRAM)["Table Capacity"] == lib.CTL_MAX_TABLE_BYTES


@pytest.mark.parametrize(
    ("command", "reason"), [("PLAY", "NO_TABLE"), ("SERPENOID", "EMPTY_ROSTER")]
)
def test_a_refused_command_names_its_reason(dev, command, reason):
    assert dev.command(command) == 0
    assert dev.flags & ControllerErrors.REFUSED
    assert page_values(dev, PROGRAM)["Refusal Reason"] == lib_value("Refusal Reason", reason)


def test_pages_not_described_are_refused_and_change_nothing(dev):
    assert dev.set("Window Page", PROGRAM.number) == 0
    described = {p.number for p in CTL.pages} | set(range(CTL.servo_pages))
    for page in range(SELECTOR.value_range()[1] + 2):
        if page in described:
            continue
        assert dev.set("Window Page", page) == ErrorFlags.RANGE, page
        assert dev.get("Window Page") == PROGRAM.number


def test_read_only_page_fields_refuse_writes(dev):
    capacity = PROGRAM.register("Table Capacity")
    # page and field in one WRITE: the page byte is checked with the rest, nothing applies
    payload = bytes([PROGRAM.number]) + capacity.decode(bytes(4)).to_bytes(4, "little")
    assert dev.one(write(CTL_ID, SELECTOR.address, payload)).error == ErrorFlags.RANGE
    assert dev.get("Window Page") == 0
    # bytes of the page no field covers refuse writes too, and read as 0
    end = max(f.end for f in PROGRAM.fields)
    assert dev.set("Window Page", PROGRAM.number) == 0
    assert dev.one(write(CTL_ID, PROGRAM.base + end, b"\x01")).error == ErrorFlags.RANGE
    assert dev.read(PROGRAM.base + end, 8) == bytes(8)


def test_a_page_write_in_one_packet_with_its_records():
    """A WRITE that sets a servo page and a record applies the new page (unchanged)."""
    dev = Device()
    payload = bytes([2, 42])  # page 2, record 0's ID -> joint 12
    assert dev.one(write(CTL_ID, SELECTOR.address, payload)).error == 0
    assert dev.servo_window(2)[0]["ID"] == 42


def test_the_description_refuses_broken_pages():
    from dataclasses import replace

    from snakebot.facts.devices import loader

    device = load().device
    clash = replace(PROGRAM, fields=(replace(PROGRAM.fields[0], name="Speed Scale"),))
    with pytest.raises(DeviceError, match="also a register's name"):
        loader._check_pages("controller.json", replace(device, pages=(clash,)))
    low = replace(PROGRAM, number=1)
    with pytest.raises(DeviceError, match="numbers run 3"):
        loader._check_pages("controller.json", replace(device, pages=(low,)))
    wide = replace(PROGRAM, fields=(replace(PROGRAM.fields[0], address=125),))
    with pytest.raises(DeviceError, match="leaves the window"):
        loader._check_pages("controller.json", replace(device, pages=(wide,)))
    with pytest.raises(DeviceError, match="taken twice"):
        loader._check_pages("controller.json", replace(device, pages=(PROGRAM, PROGRAM)))
