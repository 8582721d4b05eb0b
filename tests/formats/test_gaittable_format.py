"""Gait tables: Python encode/decode and files, the C validator, and that the two agree
on every table and every corruption (protocol/gait_table.md)."""

from __future__ import annotations

import json
import zlib

import numpy as np
import pytest
from ctl_support import CTL, c_validate, gait_tables, with_crc
from hypothesis import given
from hypothesis import strategies as st

from snakebot.core import ffi, lib
from snakebot.formats.gaittable import (
    CODES,
    HEADER_SIZE,
    JOINT_SIZE,
    MAX_JOINTS,
    MAX_TABLE_BYTES,
    GaitTable,
    GaitTableError,
    max_frames,
    read_gait,
    sidecar_path,
    table_crc,
    write_gait,
)


def python_code(data: bytes) -> int:
    try:
        GaitTable.decode(data)
    except GaitTableError as exc:
        assert exc.code is not None, exc
        return exc.code
    return 0


def simple(**changes) -> GaitTable:
    args = dict(
        joint_ids=(1, 2, 3),
        frame_period_ms=20,
        loop=True,
        limits=((100, 900), (200, 800), (0, 1023)),
        frames=np.array([[512, 512, 512], [600, 400, 0], [700, 300, 1023]]),
        metadata={"gait": "test"},
    )
    args.update(changes)
    return GaitTable(**args)


def test_constants_agree_with_c_and_controller_json():
    assert (HEADER_SIZE, JOINT_SIZE) == (lib.GT_HEADER_SIZE, lib.GT_JOINT_SIZE)
    assert MAX_JOINTS == CTL.limits["max_joints"] == lib.CTL_MAX_JOINTS
    assert MAX_TABLE_BYTES == CTL.limits["max_table_bytes"] == lib.CTL_MAX_TABLE_BYTES
    assert int.from_bytes(b"SNKG", "little") == lib.GT_MAGIC
    for name, code in CODES.items():
        assert CTL.enums["Upload Result"][name.upper()] == code
    # the documented sizing example: 200 frames x 4 joints fits
    assert max_frames(4) >= 200


def test_layout_by_hand():
    table = simple()
    data = table.encode()
    assert data[:4] == b"SNKG" and data[4] == 1 and data[5] == 3 and data[6] == 1
    assert int.from_bytes(data[8:10], "little") == 20
    assert int.from_bytes(data[10:12], "little") == 3
    assert data[16:22] == bytes([1, 0]) + (100).to_bytes(2, "little") + (900).to_bytes(2, "little")
    frames_at = 16 + 6 * 3
    # frame 1, joint 2 is 0; frame 2, joint 2 is 1023
    assert data[frames_at + 2 * (1 * 3 + 2) :][:2] == b"\x00\x00"
    assert data[frames_at + 2 * (2 * 3 + 2) :][:2] == (1023).to_bytes(2, "little")
    assert len(data) == table.size == frames_at + 2 * 9
    crc = zlib.crc32(data[:12] + data[16:])
    assert int.from_bytes(data[12:16], "little") == crc == table.crc == table_crc(data)
    assert table.image_crc == zlib.crc32(data)


@given(gait_tables(max_joints=MAX_JOINTS))
def test_round_trip(table):
    data = table.encode()
    back = GaitTable.decode(data, table.metadata)
    assert back == table
    assert np.array_equal(back.frames, table.frames)
    assert back.frames.dtype == np.uint16


@given(gait_tables(max_joints=MAX_JOINTS))
def test_c_accepts_and_reads_what_python_writes(table):
    data = table.encode()
    status, info = c_validate(data)
    assert status == lib.GT_OK
    assert (info.size, info.joint_count, info.frame_count) == (
        len(data),
        table.joint_count,
        table.frame_count,
    )
    assert info.frame_period_ms == table.frame_period_ms
    assert bool(info.flags & lib.GT_FLAG_LOOP) == table.loop
    assert info.crc == table.crc == lib.gt_crc(data, len(data))
    buf = ffi.from_buffer(data)
    for j, (sid, (lo, hi)) in enumerate(zip(table.joint_ids, table.limits, strict=True)):
        assert (lib.gt_joint_id(buf, info, j), lib.gt_joint_min(buf, info, j)) == (sid, lo)
        assert lib.gt_joint_max(buf, info, j) == hi
    got = [
        [lib.gt_frame(buf, info, f, j) for j in range(table.joint_count)]
        for f in range(table.frame_count)
    ]
    assert np.array_equal(np.array(got), table.frames)
    # out-of-range accessors are bounded
    assert lib.gt_frame(buf, info, table.frame_count, 0) == 0
    assert lib.gt_joint_id(buf, info, table.joint_count) == 0


@given(gait_tables(max_joints=4), st.data())
def test_every_single_byte_corruption_is_caught_for_the_same_reason(table, data):
    raw = bytearray(table.encode())
    at = data.draw(st.integers(0, len(raw) - 1))
    raw[at] ^= data.draw(st.integers(1, 255))
    c_status, _ = c_validate(bytes(raw))
    assert c_status != lib.GT_OK
    assert python_code(bytes(raw)) == c_status


@given(gait_tables(max_joints=4), st.data())
def test_truncation_and_trailing_bytes(table, data):
    raw = table.encode()
    cut = data.draw(st.integers(0, len(raw) - 1))
    assert c_validate(raw[:cut])[0] == python_code(raw[:cut]) == lib.GT_ERR_TRUNCATED
    extra = raw + data.draw(st.binary(min_size=1, max_size=8))
    assert c_validate(extra)[0] == python_code(extra) == lib.GT_ERR_TRAILING


@given(st.binary(max_size=64) | st.binary(min_size=16, max_size=16).map(lambda b: b"SNKG\x01" + b))
def test_c_and_python_agree_on_arbitrary_bytes(blob):
    assert c_validate(blob)[0] == python_code(blob)


def crafted(mutate) -> bytes:
    """A valid table's bytes after mutate(bytearray), with the CRC made right again."""
    raw = bytearray(simple().encode())
    mutate(raw)
    return with_crc(bytes(raw))


def _set16(raw: bytearray, at: int, value: int) -> None:
    raw[at : at + 2] = value.to_bytes(2, "little")


@pytest.mark.parametrize(
    "mutate, reason",
    [
        (lambda r: r.__setitem__(slice(0, 4), b"SNKX"), "bad_magic"),
        (lambda r: r.__setitem__(4, 2), "bad_version"),
        (lambda r: r.__setitem__(5, 0), "bad_joint_count"),
        (lambda r: r.__setitem__(5, 19), "bad_joint_count"),
        (lambda r: r.__setitem__(6, 0x81), "bad_flags"),
        (lambda r: r.__setitem__(7, 1), "bad_flags"),
        (lambda r: _set16(r, 8, 0), "bad_period"),
        (lambda r: _set16(r, 10, 0), "bad_frame_count"),
        (lambda r: _set16(r, 10, 0xFFFF), "too_big"),
        (lambda r: _set16(r, 10, 4), "truncated"),
        (lambda r: _set16(r, 10, 2), "trailing_bytes"),
        (lambda r: r.__setitem__(17, 1), "bad_flags"),  # joint 0's reserved byte
        (lambda r: r.__setitem__(22, 1), "bad_joint_id"),  # joint 1 reuses ID 1
        (lambda r: r.__setitem__(16, 254), "bad_joint_id"),
        (lambda r: _set16(r, 18, 901), "bad_limits"),  # joint 0: min above max
        (lambda r: _set16(r, 32, 1024), "bad_limits"),  # joint 2: max above 1023
        (lambda r: _set16(r, 34, 99), "frame_out_of_limits"),  # frame 0, joint 0 below 100
    ],
)
def test_each_layout_fault_has_its_code_on_both_sides(mutate, reason):
    raw = crafted(mutate)
    with pytest.raises(GaitTableError) as caught:
        GaitTable.decode(raw)
    assert caught.value.reason == reason
    assert c_validate(raw)[0] == CODES[reason]
    assert lib.gt_strerror(CODES[reason]) != ffi.NULL


def test_crc_mismatch_message_names_problem_and_fix():
    raw = bytearray(simple().encode())
    raw[-1] ^= 1
    with pytest.raises(GaitTableError, match="CRC mismatch.*regenerate") as caught:
        GaitTable.decode(bytes(raw))
    assert caught.value.code == lib.GT_ERR_CRC == c_validate(bytes(raw))[0]
    assert ffi.string(lib.gt_strerror(lib.GT_ERR_CRC)) == b"CRC mismatch"


def test_constructor_refuses_what_the_controller_would():
    most = (MAX_TABLE_BYTES - HEADER_SIZE - JOINT_SIZE * 4) // (2 * 4)
    with pytest.raises(GaitTableError, match=f"too large.*at most {most} frames for 4 joints"):
        GaitTable((1, 2, 3, 4), 20, True, ((0, 1023),) * 4, np.full((most + 1, 4), 512))
    GaitTable((1, 2, 3, 4), 20, True, ((0, 1023),) * 4, np.full((most, 4), 512))
    with pytest.raises(GaitTableError) as caught:
        simple(frames=np.array([[512, 512, 512], [50, 400, 0]]))
    assert caught.value.reason == "frame_out_of_limits" and "frame 1, joint 0" in str(caught.value)
    with pytest.raises(GaitTableError, match="whole ticks"):
        simple(frames=np.array([[512.5, 512, 512]]))
    with pytest.raises(GaitTableError, match="given twice"):
        simple(joint_ids=(1, 1, 2))
    with pytest.raises(GaitTableError, match="one column per joint"):
        simple(frames=np.zeros((3, 2)))
    with pytest.raises(GaitTableError, match="1..18 joints"):
        GaitTable(tuple(range(19)), 20, True, ((0, 1023),) * 19, np.full((1, 19), 512))
    with pytest.raises(GaitTableError):
        simple(frame_period_ms=0)


def test_duration():
    assert simple(loop=True).duration_ms == 60
    assert simple(loop=False).duration_ms == 40


def test_files_round_trip_with_metadata(tmp_path):
    predicted = {"dx": 0.1, "dy": 0.2, "dtheta": 0.0}
    metadata = {"gait": "serpenoid", "A": 0.5, "predicted": predicted, "own": {"vx": [0.1]}}
    table = simple(metadata=metadata)
    path = tmp_path / "walk.gait"
    write_gait(path, table)
    assert path.read_bytes() == table.encode()
    sidecar = json.loads(sidecar_path(path).read_text())
    assert sidecar["metadata"] == table.metadata
    assert sidecar["table"]["crc32"] == table.image_crc
    back = read_gait(path)
    assert back == table and back.metadata == table.metadata
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.gait", "walk.gait.json"]


def test_metadata_of_a_shape_snakebot_cannot_read_is_not_written(tmp_path):
    path = tmp_path / "walk.gait"
    with pytest.raises(GaitTableError, match="predicted is") as caught:
        write_gait(path, simple(metadata={"predicted": {"vx": [0.1, 0.2]}}))
    assert caught.value.reason == "not_json"
    assert list(tmp_path.iterdir()) == []


def test_binary_alone_reads_with_empty_metadata(tmp_path):
    path = tmp_path / "bare.gait"
    path.write_bytes(simple().encode())
    assert read_gait(path).metadata == {}


def test_failed_write_leaves_old_files_untouched(tmp_path):
    path = tmp_path / "walk.gait"
    old = simple(metadata={"v": 1})
    write_gait(path, old)
    before = (path.read_bytes(), sidecar_path(path).read_text())
    with pytest.raises(GaitTableError, match="not JSON-able") as caught:
        write_gait(path, simple(loop=False, metadata={"array": np.arange(3)}))
    assert caught.value.reason == "not_json"
    assert (path.read_bytes(), sidecar_path(path).read_text()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.gait", "walk.gait.json"]


def test_write_into_missing_directory_is_a_clear_error(tmp_path):
    with pytest.raises(GaitTableError, match="cannot write gait table"):
        write_gait(tmp_path / "nowhere" / "walk.gait", simple())


def test_stale_sidecar_is_noticed(tmp_path):
    path = tmp_path / "walk.gait"
    write_gait(path, simple(metadata={"v": 1}))
    path.write_bytes(simple(loop=False).encode())  # binary replaced, sidecar not
    with pytest.raises(GaitTableError, match="belongs to another table") as caught:
        read_gait(path)
    assert caught.value.reason == "sidecar_mismatch"


def test_missing_and_corrupt_files(tmp_path):
    with pytest.raises(GaitTableError, match="cannot read gait table"):
        read_gait(tmp_path / "absent.gait")
    path = tmp_path / "cut.gait"
    path.write_bytes(simple().encode()[:30])
    with pytest.raises(GaitTableError, match="truncated") as caught:
        read_gait(path)
    assert caught.value.code == lib.GT_ERR_TRUNCATED
