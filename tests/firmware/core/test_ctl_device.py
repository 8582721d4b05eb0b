"""The controller as a Protocol 1.0 device: raw packets from snakebot.formats.protocol's builders
go into the C core (ctl_device) byte by byte; its status packets come back."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from ctl_support import CTL, CTL_ID, Device, gait_tables
from hypothesis import given, settings
from hypothesis import strategies as st

from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import (
    BROADCAST_ID,
    ErrorFlags,
    Instruction,
    encode_packet,
    ping,
    read,
    reg_write,
    reset,
    sync_write,
    write,
)
from snakebot.link.controller import (
    Command,
    ControllerErrors,
    ControllerTableError,
    State,
    UploadResult,
    chunk_writes,
    commit_write,
)
from snakebot.link.controller.limits import encode_limits


def table(**changes) -> GaitTable:
    args = dict(
        joint_ids=(11, 12, 13),
        frame_period_ms=20,
        loop=True,
        limits=((200, 824), (200, 824), (200, 824)),
        frames=np.array([[512, 512, 512], [600, 450, 300], [700, 400, 250], [650, 420, 260]]),
    )
    args.update(changes)
    return GaitTable(**args)


@pytest.fixture
def dev() -> Device:
    return Device()


def test_ping_answers_only_at_its_id(dev):
    r = dev.one(ping(CTL_ID))
    assert (r.id, r.error, r.params) == (CTL_ID, 0, b"")
    assert dev.transact(ping(1)) == []
    assert dev.transact(ping(BROADCAST_ID)) == []


def test_registers_start_at_their_defaults(dev):
    values = CTL.decode(0, dev.read(0, 127))
    # the registers after the servo window (the robot's limits)
    window_end = CTL.servo_window_address + CTL.servo_records * CTL.servo_record_size
    values.update(CTL.decode(window_end, dev.read(window_end, 256 - window_end)))
    for reg in CTL.registers:
        if reg.readable and reg.size <= 4:
            # the READ itself is the first packet counted
            expected = 1 if reg.name == "PC Packets" else reg.default
            assert values[reg.name] == expected, reg.name
    window = dev.servo_window(0)
    for field in CTL.servo_fields:
        assert window[0][field.name] == field.default, field.name


def test_write_checks_ranges_like_a_servo(dev):
    assert dev.set("Speed Scale", 512) == 0 and dev.get("Speed Scale") == 512
    assert dev.set("Speed Scale", 2000) == ErrorFlags.RANGE
    assert dev.get("Speed Scale") == 512  # refused writes change nothing
    assert dev.set("Steering Offset", -40) == 0 and dev.get("Steering Offset") == -40
    assert dev.set("Steering Offset", -600) == ErrorFlags.RANGE
    assert dev.set("Serp Omega", -31416) == 0 and dev.get("Serp Omega") == -31416
    # read-only register, unlisted address, past the end
    assert dev.one(write(CTL_ID, CTL.register("State").address, b"\x01")).error == ErrorFlags.RANGE
    assert dev.one(write(CTL_ID, 59, b"\x00")).error == ErrorFlags.RANGE
    assert dev.one(write(CTL_ID, 255, b"\x00\x00")).error == ErrorFlags.RANGE
    # a write touching a bad byte is refused whole
    scale = CTL.register("Speed Scale").address
    # Joint Count 1, Speed Scale 512 (fine), Steering Offset 0x0905 (too big)
    assert dev.one(write(CTL_ID, scale - 1, b"\x01\x00\x02\x05\x09")).error == ErrorFlags.RANGE
    assert dev.get("Joint Count") == 0 and dev.get("Speed Scale") == 512


def test_half_a_register_is_checked_as_it_would_become(dev):
    scale = CTL.register("Speed Scale").address
    assert dev.one(write(CTL_ID, scale + 1, b"\x03")).error == 0  # 0x0300 = 768
    assert dev.get("Speed Scale") == 768
    assert dev.one(write(CTL_ID, scale + 1, b"\x05")).error == ErrorFlags.RANGE  # 1280


def test_bad_reads_and_unknown_instructions(dev):
    assert dev.one(read(CTL_ID, 250, 10)).error == ErrorFlags.RANGE
    assert dev.one(encode_packet(CTL_ID, Instruction.READ, b"\x00\x00")).error == ErrorFlags.RANGE
    # a reply of 245 bytes of data would pass the 250-byte packet cap
    assert dev.one(encode_packet(CTL_ID, Instruction.READ, b"\x00\xf5")).error == ErrorFlags.RANGE
    assert dev.one(encode_packet(CTL_ID, Instruction.READ, b"\x00")).error == ErrorFlags.INSTRUCTION
    assert dev.one(reg_write(CTL_ID, 16, b"\x00\x02")).error == ErrorFlags.INSTRUCTION
    assert dev.one(encode_packet(CTL_ID, 0x42)).error == ErrorFlags.INSTRUCTION
    assert len(dev.read(0, 244)) == 244


def test_write_only_registers_read_as_zero(dev):
    assert dev.set("Upload Offset", 0) == 0
    data_reg = CTL.register("Upload Data")
    assert dev.one(write(CTL_ID, data_reg.address, b"\xaa" * 8)).error == 0
    assert dev.read(data_reg.address, 8) == bytes(8)


def test_id_change_and_status_return_level(dev):
    r = dev.one(write(CTL_ID, CTL.register("ID").address, b"\x07"))
    assert r.id == CTL_ID and r.error == 0  # the reply still comes from the old ID
    assert dev.transact(ping(CTL_ID)) == []
    assert dev.one(ping(7)).id == 7
    srl = CTL.register("Status Return Level").address
    assert dev.one(write(7, srl, b"\x01")).error == 0
    assert dev.transact(write(7, 20, b"\x00\x01")) == []  # WRITE no longer answered
    assert dev.one(read(7, 20, 2)).params == b"\x00\x01"
    assert dev.transact(write(7, srl, b"\x00")) == []
    assert dev.transact(read(7, 20, 2)) == []
    assert dev.one(ping(7)).error == 0  # PING is always answered
    # RESET: defaults again (ID 200), answered from the old ID (if the level allows)
    assert dev.transact(reset(7)) == []
    assert dev.one(ping(CTL_ID)).id == CTL_ID
    assert dev.get("Status Return Level") == 2


def test_reset_restores_defaults_but_keeps_the_table(dev):
    t = table()
    assert dev.upload(t.encode()) == UploadResult.OK
    assert dev.set("Speed Scale", 100) == 0
    r = dev.one(reset(CTL_ID))
    assert r.error == 0
    assert dev.get("Speed Scale") == 256
    assert dev.get("Table CRC") == t.image_crc and dev.get("Joint Count") == 3


def test_reset_shows_the_table_again_only_while_it_fits_the_robot_limits(dev):
    """RESET re-reads the active table from its header (it was validated when it became
    active), but checks it against the robot's limits again: they may have changed."""
    t = table()
    assert dev.upload(t.encode()) == UploadResult.OK

    def set_limits(low: int, high: int) -> None:
        blob = encode_limits({sid: (low, high) for sid in (11, 12, 13)})
        for address, data in chunk_writes(blob, controller=CTL):
            assert dev.one(write(CTL_ID, address, data)).error == 0
        assert dev.one(write(CTL_ID, *commit_write(blob, CTL, what="LIMITS"))).error == 0
        assert dev.get("Upload Result") == UploadResult.OK

    set_limits(100, 900)  # the table's 200..824 fit
    assert dev.one(reset(CTL_ID)).error == 0
    assert (dev.get("Table Size"), dev.get("Table CRC")) == (t.size, t.image_crc)
    assert [r["ID"] for r in dev.servo_window(0)[:3]] == [11, 12, 13]

    set_limits(300, 700)  # they no longer do: the registers stop showing it
    assert dev.one(reset(CTL_ID)).error == 0
    assert (dev.get("Table Size"), dev.get("Table CRC"), dev.get("Joint Count")) == (0, 0, 0)

    set_limits(100, 900)  # and show it again once they do
    assert dev.one(reset(CTL_ID)).error == 0
    assert (dev.get("Table Size"), dev.get("Table CRC")) == (t.size, t.image_crc)


def test_broadcast_write_and_sync_write_apply_silently(dev):
    amp = CTL.register("Serp Amplitude").address
    assert dev.transact(write(BROADCAST_ID, amp, (700).to_bytes(2, "little"))) == []
    assert dev.get("Serp Amplitude") == 700
    packet = sync_write(
        amp, 2, {5: (800).to_bytes(2, "little"), CTL_ID: (900).to_bytes(2, "little")}
    )
    assert dev.transact(packet) == []
    assert dev.get("Serp Amplitude") == 900


def test_garbage_between_packets_is_survived_and_counted(dev):
    junk = b"\x00\xff\xff\x01\x02\x03\xff\xff\xff\xc8\x04\x02\x00\x01\x99" + b"\x00" * 250
    assert dev.transact(junk + ping(CTL_ID))[0].id == CTL_ID
    assert dev.get("PC Errors") >= 1
    assert dev.get("PC Packets") >= 2


def test_upload_commit_makes_the_table_active(dev):
    t = table()
    assert dev.upload(t.encode(), chunk=5) == UploadResult.OK
    assert dev.get("Table Size") == t.size
    assert dev.get("Table CRC") == t.image_crc
    assert (dev.get("Table Joints"), dev.get("Table Frames")) == (3, 4)
    assert (dev.get("Table Period"), dev.get("Table Flags"), dev.get("Loop")) == (20, 1, 1)
    assert dev.flags == 0
    roster = dev.servo_window(0)[:3]
    assert [r["ID"] for r in roster] == [11, 12, 13]
    assert [(r["Min Tick"], r["Max Tick"]) for r in roster] == [(200, 824)] * 3
    assert dev.get("Joint Count") == 3


@settings(max_examples=25)
@given(gait_tables(max_joints=18), st.integers(1, 64))
def test_any_valid_table_uploads_in_any_chunk_size(t, chunk):
    dev = Device()
    assert dev.upload(t.encode(), chunk=chunk) == UploadResult.OK
    assert dev.get("Table CRC") == t.image_crc


def test_out_of_order_chunks_are_fine(dev):
    data = table().encode()
    chunks = [(at, data[at : at + 16]) for at in range(0, len(data), 16)]
    offset = CTL.register("Upload Offset").address
    for at, chunk in [chunks[0], *reversed(chunks[1:])]:
        assert dev.one(write(CTL_ID, offset, at.to_bytes(2, "little") + chunk)).error == 0
    assert dev.commit(len(data), zlib.crc32(data)) == 0
    assert dev.get("Upload Result") == UploadResult.OK


def _failed_upload_keeps(dev: Device, good: GaitTable, result: int, flag: int) -> None:
    assert dev.get("Upload Result") == result
    assert dev.flags & flag
    assert dev.get("Table CRC") == good.image_crc  # the old table is still the active one
    assert dev.command("PLAY") == 0 and dev.state == State.PLAYING


@pytest.mark.parametrize(
    "spoil, result, flag",
    [
        # the transfer went wrong: a byte changed on the way
        ("transfer", UploadResult.TRANSFER_CRC, ControllerErrors.UPLOAD_CRC),
        # the upload stopped half-way and the host committed anyway
        ("interrupted", UploadResult.INCOMPLETE, ControllerErrors.UPLOAD_LENGTH),
        # a table that is corrupt in itself, sent faithfully
        ("table_crc", UploadResult.CRC_MISMATCH, ControllerErrors.UPLOAD_CRC),
        ("layout", UploadResult.BAD_MAGIC, ControllerErrors.UPLOAD_LAYOUT),
        ("short", UploadResult.TRUNCATED, ControllerErrors.UPLOAD_LENGTH),
        ("zero", UploadResult.BAD_LENGTH, ControllerErrors.UPLOAD_LENGTH),
    ],
)
def test_failed_commit_leaves_the_old_table_and_says_why(dev, spoil, result, flag):
    good = table()
    assert dev.upload(good.encode()) == UploadResult.OK
    new = table(loop=False).encode()
    if spoil == "transfer":
        dev.upload(new[:10] + bytes([new[10] ^ 4]) + new[11:], commit=False)
        dev.commit(len(new), zlib.crc32(new))
    elif spoil == "interrupted":
        dev.upload(new[:-20], commit=False)
        # the upload restarts at offset 0, so the old table's bytes do not count
        dev.commit(len(new), zlib.crc32(new))
    elif spoil == "table_crc":
        bad = new[:-1] + bytes([new[-1] ^ 1])
        dev.upload(bad)
    elif spoil == "layout":
        dev.upload(b"XNKG" + new[4:])
    elif spoil == "short":
        dev.upload(new[:-2])
    else:
        dev.commit(0, 0)
    _failed_upload_keeps(dev, good, result, flag)


def test_a_good_commit_clears_the_upload_error(dev):
    dev.commit(0, 0)
    assert dev.flags & ControllerErrors.UPLOAD_LENGTH
    assert dev.upload(table().encode()) == UploadResult.OK
    assert dev.flags == 0


def test_writing_past_the_staging_area_is_refused(dev):
    offset = CTL.register("Upload Offset").address
    end = CTL.limits["max_table_bytes"]  # the host devices' capacity: the largest board's
    r = dev.one(write(CTL_ID, offset, (end - 8).to_bytes(2, "little") + bytes(16)))
    assert r.error == ErrorFlags.RANGE
    assert dev.flags & ControllerErrors.UPLOAD_LENGTH


def test_commit_stops_playback(dev):
    assert dev.upload(table().encode()) == UploadResult.OK
    assert dev.command("PLAY") == 0 and dev.state == State.PLAYING
    assert dev.upload(table(loop=False).encode()) == UploadResult.OK
    assert dev.state == State.IDLE
    assert dev.get("Loop") == 0


def test_commands_that_cannot_run_are_refused(dev):
    assert dev.command("PLAY") == 0  # no table yet
    assert dev.state == State.IDLE and dev.flags & ControllerErrors.REFUSED
    assert dev.command("CLEAR") == 0 and dev.flags == 0
    assert dev.command("SERPENOID") == 0  # empty roster
    assert dev.flags & ControllerErrors.REFUSED
    assert dev.set("Command", 9) == ErrorFlags.RANGE
    assert dev.get("Command") == 0


def test_servo_window_pages_and_roster_writes(dev):
    assert dev.set("Joint Count", 8) == 0
    page, slot = CTL.servo_page(7)
    assert dev.set("Window Page", page) == 0
    rec = CTL.servo_address(slot, "ID")
    # ID, Reverse, Zero Tick in one write
    assert dev.one(write(CTL_ID, rec, bytes([42, 1]) + (300).to_bytes(2, "little"))).error == 0
    joint7 = dev.servo_window(page)[slot]
    assert (joint7["ID"], joint7["Reverse"], joint7["Zero Tick"]) == (42, 1, 300)
    assert dev.servo_window(0)[slot]["ID"] == 0  # page 0 shows other joints
    # telemetry fields are read-only; ranges are checked
    assert dev.set("Window Page", page) == 0
    pos = CTL.servo_address(slot, "Present Position")
    assert dev.one(write(CTL_ID, pos, b"\x00\x02")).error == ErrorFlags.RANGE
    zero = CTL.servo_address(slot, "Zero Tick")
    assert dev.one(write(CTL_ID, zero, (1024).to_bytes(2, "little"))).error == ErrorFlags.RANGE
    # page and record in one write: the new page applies
    payload = bytes([1, 77])  # Window Page = 1, then record 0's ID = 77 -> joint 6
    assert dev.one(write(CTL_ID, CTL.register("Window Page").address, payload)).error == 0
    assert dev.servo_window(1)[0]["ID"] == 77


def test_command_register_values_match(dev):
    assert Command.PLAY == CTL.enums["Command"]["PLAY"]


def test_host_commit_write_drives_the_device(dev):
    data = table().encode()
    for address, payload in chunk_writes(data, 33):
        assert dev.one(write(CTL_ID, address, payload)).error == 0
    address, payload = commit_write(data)
    assert dev.one(write(CTL_ID, address, payload)).error == 0
    assert dev.get("Upload Result") == UploadResult.OK
    assert dev.get("Table CRC") == zlib.crc32(data)


def test_host_upload_writes_refuse_what_cannot_fit():
    with pytest.raises(ControllerTableError, match="chunk must be 1..64"):
        chunk_writes(b"x" * 10, 65)
    with pytest.raises(ControllerTableError, match="cannot be uploaded"):
        chunk_writes(b"x" * (CTL.limits["max_table_bytes"] + 1))
    assert [len(p) for _, p in chunk_writes(b"x" * 130)] == [66, 66, 4]
