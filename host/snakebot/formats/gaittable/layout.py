"""The gait-table binary layout (protocol/gait_table.md): constants, encoding, decoding.

The decoder runs the firmware's checks in the firmware's order, so a byte string is
refused here for exactly the reason ``gt_validate()`` would give.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

from snakebot.facts import devices
from snakebot.facts.controller import load as load_controller
from snakebot.formats.gaittable.errors import GaitTableError

MAGIC = b"SNKG"
VERSION = 1
HEADER = struct.Struct("<4sBBBBHHI")  # magic, version, joints, flags, reserved, period, frames, crc
HEADER_SIZE = HEADER.size  # 16
CRC_OFFSET = 12
JOINT = struct.Struct("<BBHH")  # id, reserved, min tick, max tick
JOINT_SIZE = JOINT.size  # 6
FLAG_LOOP = 0x01
MAX_TICK = devices.ax12().require_position().range[1]
MAX_ID = 253
MAX_PERIOD_MS = 0xFFFF
MAX_FRAME_COUNT = 0xFFFF

_limits = load_controller().limits
MAX_JOINTS: int = _limits["max_joints"]
MAX_TABLE_BYTES: int = _limits["max_table_bytes"]


def table_size(joints: int, frames: int) -> int:
    """Bytes of a table with ``joints`` joints and ``frames`` frames."""
    return HEADER_SIZE + JOINT_SIZE * joints + 2 * joints * frames


def max_frames(joints: int, capacity: int = MAX_TABLE_BYTES) -> int:
    """The most frames a table of ``joints`` joints can have and still fit ``capacity``
    bytes (by default the largest board's; a controller reports its own as Table
    Capacity)."""
    return (capacity - HEADER_SIZE - JOINT_SIZE * joints) // (2 * joints)


def table_crc(data: bytes) -> int:
    """The table CRC: CRC-32 of the table with its 4 CRC bytes (offset 12) left out."""
    return zlib.crc32(data[HEADER_SIZE:], zlib.crc32(data[:CRC_OFFSET]))


def too_big_message(joints: int, frames: int) -> str:
    return (
        f"gait table too large for the controller: {joints} joints x {frames} frames need "
        f"{table_size(joints, frames)} bytes, the controller holds {MAX_TABLE_BYTES}; use at "
        f"most {max(max_frames(joints), 0)} frames for {joints} joints (a longer frame period "
        "or fewer cycles)"
    )


def encode(
    joint_ids: tuple[int, ...],
    frame_period_ms: int,
    loop: bool,
    limits: tuple[tuple[int, int], ...],
    frames: np.ndarray,
) -> bytes:
    """The table's bytes (inputs already validated by GaitTable)."""
    joints = len(joint_ids)
    header = HEADER.pack(
        MAGIC, VERSION, joints, FLAG_LOOP if loop else 0, 0, frame_period_ms, len(frames), 0
    )
    pairs = zip(joint_ids, limits, strict=True)
    records = b"".join(JOINT.pack(i, 0, lo, hi) for i, (lo, hi) in pairs)
    body = records + np.ascontiguousarray(frames, dtype="<u2").tobytes()
    crc = zlib.crc32(body, zlib.crc32(header[:CRC_OFFSET]))
    return header[:CRC_OFFSET] + crc.to_bytes(4, "little") + body


def _fail(reason: str, message: str) -> GaitTableError:
    return GaitTableError(message, reason)


Decoded = tuple[tuple[int, ...], int, bool, tuple[tuple[int, int], ...], np.ndarray]


def decode(data: bytes) -> Decoded:
    """(joint_ids, frame_period_ms, loop, limits, frames) from a table's bytes, checked in
    the firmware's order; GaitTableError with the firmware's reason otherwise."""
    data = bytes(data)
    regenerate = "regenerate the gait and write it again"
    if len(data) < HEADER_SIZE:
        raise _fail(
            "truncated",
            f"gait table truncated: {len(data)} bytes, not even the {HEADER_SIZE}-byte header; "
            f"the file was cut short: {regenerate}",
        )
    magic, version, joints, flags, reserved, period, frames, crc = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise _fail(
            "bad_magic",
            f"not a gait table: it starts with {magic!r}, not {MAGIC!r}; give a .gait file "
            "written by snakebot",
        )
    if version != VERSION:
        raise _fail(
            "bad_version",
            f"gait table version {version} is unknown (this snakebot reads version "
            f"{VERSION}); regenerate it with this snakebot",
        )
    if not 1 <= joints <= MAX_JOINTS:
        raise _fail(
            "bad_joint_count",
            f"gait table has {joints} joints; the controller drives 1..{MAX_JOINTS}: {regenerate}",
        )
    if flags & ~FLAG_LOOP or reserved:
        raise _fail(
            "bad_flags",
            f"gait table header has unknown flags 0x{flags:02x} / reserved byte {reserved}: "
            f"it is corrupt or from a newer snakebot; {regenerate}",
        )
    if period == 0:
        raise _fail("bad_period", f"gait table frame period is 0 ms: {regenerate}")
    if frames == 0:
        raise _fail("bad_frame_count", f"gait table has no frames: {regenerate}")
    size = table_size(joints, frames)
    if size > MAX_TABLE_BYTES:
        raise _fail("too_big", too_big_message(joints, frames))
    if len(data) < size:
        raise _fail(
            "truncated",
            f"gait table truncated: {len(data)} of its {size} bytes; the file was cut short: "
            f"{regenerate}",
        )
    if len(data) > size:
        raise _fail(
            "trailing_bytes",
            f"gait table has {len(data) - size} bytes after its end ({size} bytes): the file "
            f"is corrupt; {regenerate}",
        )
    actual = table_crc(data)
    if actual != crc:
        raise _fail(
            "crc_mismatch",
            f"gait table CRC mismatch: stored 0x{crc:08x}, bytes give 0x{actual:08x}; the "
            f"file is corrupt: {regenerate}",
        )
    ids: list[int] = []
    limits: list[tuple[int, int]] = []
    for j in range(joints):
        sid, res, lo, hi = JOINT.unpack_from(data, HEADER_SIZE + JOINT_SIZE * j)
        if res:
            raise _fail("bad_flags", f"joint {j} has reserved byte {res} (must be 0): {regenerate}")
        if sid > MAX_ID or sid in ids:
            why = "above 253" if sid > MAX_ID else "used by an earlier joint"
            raise _fail(
                "bad_joint_id",
                f"joint {j} has servo ID {sid}, {why}: fix the robot description",
            )
        if lo > hi or hi > MAX_TICK:
            raise _fail(
                "bad_limits",
                f"joint {j} (ID {sid}) has limits {lo}..{hi}: need min <= max <= {MAX_TICK}; "
                "fix the robot description",
            )
        ids.append(sid)
        limits.append((lo, hi))
    offset = HEADER_SIZE + JOINT_SIZE * joints
    values = np.frombuffer(data, dtype="<u2", count=joints * frames, offset=offset)
    values = values.reshape(frames, joints).astype(np.uint16)
    check_frames(values, tuple(limits), tuple(ids))
    return tuple(ids), period, bool(flags & FLAG_LOOP), tuple(limits), values


def check_frames(
    frames: np.ndarray, limits: tuple[tuple[int, int], ...], ids: tuple[int, ...]
) -> None:
    """GaitTableError (frame_out_of_limits) naming the first value outside its limits."""
    lo = np.array([a for a, _ in limits])
    hi = np.array([b for _, b in limits])
    bad = (frames < lo) | (frames > hi)
    if bad.any():
        f, j = (int(x) for x in np.argwhere(bad)[0])
        raise _fail(
            "frame_out_of_limits",
            f"frame {f}, joint {j} (ID {ids[j]}) is {int(frames[f, j])} ticks, outside its "
            f"limits {limits[j][0]}..{limits[j][1]}: clamp the gait or widen the limits in "
            "the robot description",
        )
