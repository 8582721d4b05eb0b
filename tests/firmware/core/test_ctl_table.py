"""The controller's control table: its description is consistent, the generated C header
is up to date, and the C core and the Python view agree on every address."""

from __future__ import annotations

import pytest
from protocol_support import gen_headers

from snakebot.core import lib
from snakebot.link.controller import (
    Command,
    ControllerErrors,
    ControllerTableError,
    State,
    UploadResult,
    load,
)
from snakebot.paths import REPO_ROOT

CTL = load()


def test_generated_header_and_doc_tables_are_up_to_date():
    expected = gen_headers().rendered()
    assert {
        REPO_ROOT / "firmware" / "core" / "ctl_table.h",
        REPO_ROOT / "protocol" / "controller.md",
    } <= set(expected)
    for path, text in expected.items():
        assert path.read_text() == text, f"{path} is stale: run protocol/gen_headers.py"


def test_registers_fit_without_overlap():
    used: dict[int, str] = {}
    for reg in CTL.registers:
        for a in range(reg.address, reg.end):
            assert a not in used, f"{reg.name} overlaps {used[a]} at {a}"
            used[a] = reg.name
    window_end = CTL.servo_window_address + CTL.servo_records * CTL.servo_record_size
    for a in range(CTL.servo_window_address, window_end):
        assert a not in used, f"servo window overlaps {used[a]}"
    assert window_end <= CTL.table_size == lib.CTL_CONTROL_TABLE_BYTES == 256
    offsets = sorted((f.address, f.end) for f in CTL.servo_fields)
    assert offsets[0][0] == 0 and offsets[-1][1] == CTL.servo_record_size
    assert all(a[1] == b[0] for a, b in zip(offsets, offsets[1:], strict=False))
    # the servo window shows every roster joint on some page
    pages = CTL.servo_pages
    assert pages * CTL.servo_records == CTL.limits["max_joints"]


def test_defaults_lie_in_their_ranges():
    for reg in (*CTL.registers, *CTL.servo_fields):
        if reg.writable and reg.size <= 4 and reg.access == "RW":
            assert reg.accepts(reg.default), reg.name


def test_c_addresses_match_python_names():
    for reg in CTL.registers:
        macro = "CTL_" + "".join(c if c.isalnum() else "_" for c in reg.name.upper())
        assert getattr(lib, macro) == reg.address, reg.name
        assert getattr(lib, macro + "_SIZE") == reg.size, reg.name
    for field in CTL.servo_fields:
        macro = "CTL_REC_" + "".join(c if c.isalnum() else "_" for c in field.name.upper())
        assert getattr(lib, macro) == field.address
    assert lib.CTL_SERVO_WINDOW == CTL.servo_window_address
    assert lib.CTL_SERVO_RECORD_SIZE == CTL.servo_record_size
    assert lib.CTL_UPLOAD_WINDOW == CTL.register("Upload Data").size
    assert lib.CTL_DEFAULT_ID == CTL.default_id == 200
    assert lib.CTL_STATE_SAFE == State.SAFE and lib.CTL_COMMAND_CLEAR == Command.CLEAR
    assert lib.CTL_ERROR_FLAGS_BUS_LOSS == ControllerErrors.BUS_LOSS
    assert lib.CTL_UPLOAD_RESULT_TRANSFER_CRC == UploadResult.TRANSFER_CRC


def test_upload_window_is_usable_in_one_packet():
    # offset + data in one WRITE must fit the 250-byte packet cap: 7 bytes of framing
    offset = CTL.register("Upload Offset")
    data = CTL.register("Upload Data")
    assert data.address == offset.end
    assert 7 + offset.size + data.size <= 250
    # Upload Length also names firmware images (Upload Commit FIRMWARE_CHECK): wider.
    assert CTL.register("Upload Length").max >= CTL.limits["max_table_bytes"]


def test_register_encoding():
    steer = CTL.register("Steering Offset")
    assert steer.encode(-3) == b"\xfd\xff" and steer.decode(b"\xfd\xff") == -3
    with pytest.raises(ControllerTableError, match="takes -512..512"):
        steer.encode(600)
    with pytest.raises(ControllerTableError, match="not writable"):
        CTL.register("State").encode(1)
    with pytest.raises(ControllerTableError, match="no register"):
        CTL.register("Warp Drive")
    assert CTL.servo_page(13) == (2, 1)
    assert CTL.servo_address(1, "Present Position") == CTL.servo_window_address + 21 + 10
