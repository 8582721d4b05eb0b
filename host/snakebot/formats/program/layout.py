"""The program blob (protocol/program.md): typed segments, encoding and decoding.

Sizes, kinds and codes come from the C core's header (``firmware/core/prog_run.h``,
through cffi), which the firmware compiles against, so the two cannot drift apart.
Whether a blob is acceptable is decided by the same C code the controller runs
(``check``), not by a second implementation.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

from snakebot.core import ffi, lib
from snakebot.formats.gaittable import table_crc
from snakebot.formats.program.errors import ProgramError, refusal

MAGIC = struct.pack("<I", lib.PROG_MAGIC)
HEADER = struct.Struct(
    "<4sBBBBHHI"
)  # magic, version, joints, segments, blocks, period, frames, crc
JOINT = struct.Struct("<BBHHH")  # id, flags, zero tick, min tick, max tick
SEGMENT = struct.Struct("<BB5H")  # kind, reserved, five 16-bit fields (signedness per kind)
PERIODIC_JOINT = struct.Struct("<hhh")  # offset rate mrad/s, sine and cosine amplitude mrad
CAPACITY = lib.CTL_MAX_TABLE_BYTES
assert HEADER.size == lib.PROG_HEADER_SIZE and JOINT.size == lib.PROG_JOINT_SIZE
assert SEGMENT.size == lib.PROG_SEGMENT_SIZE
assert PERIODIC_JOINT.size == lib.PROG_PERIODIC_JOINT_SIZE


@dataclass(frozen=True)
class JointRecord:
    """One joint: its servo, the tick at angle 0, which way it turns, its tick limits."""

    servo_id: int
    zero: int
    low: int
    high: int
    reverse: bool = False

    @property
    def sign(self) -> int:
        return -1 if self.reverse else 1


@dataclass(frozen=True)
class TableSegment:
    """Play the program's frames first..first+count-1, repetitions times, one per step."""

    first: int
    count: int
    repetitions: int = 1

    @property
    def steps(self) -> int:
        return self.count * self.repetitions


@dataclass(frozen=True)
class SerpenoidSegment:
    """phi_k = A sin(omega t + k delta) + phi0 (mrad, mrad/s), for ``steps`` steps."""

    amp_mrad: int
    omega_mrad_s: int
    delta_mrad: int
    phi0_mrad: int
    steps: int


@dataclass(frozen=True)
class PeriodicSegment:
    """phi_k = rate_k t + a_k sin(omega t) + b_k cos(omega t), with block ``block``'s
    per-joint (rate mrad/s, a mrad, b mrad), for ``steps`` steps."""

    block: int
    omega_mrad_s: int
    steps: int


Segment = TableSegment | SerpenoidSegment | PeriodicSegment
Block = tuple[tuple[int, int, int], ...]  # per joint (rate, sine amplitude, cosine amplitude)


@dataclass(frozen=True)
class Program:
    """A controller program: joints, step period, segments, periodic blocks and frames."""

    period_ms: int
    joints: tuple[JointRecord, ...]
    segments: tuple[Segment, ...]
    blocks: tuple[Block, ...] = ()
    frames: tuple[tuple[int, ...], ...] = field(default=())  # frames[f][k], ticks

    @property
    def total_steps(self) -> int:
        return sum(s.steps for s in self.segments)

    @property
    def joint_ids(self) -> tuple[int, ...]:
        return tuple(j.servo_id for j in self.joints)

    @property
    def joint_count(self) -> int:
        return len(self.joints)

    @property
    def duration_s(self) -> float:
        return self.total_steps * self.period_ms / 1000.0

    def encode(self) -> bytes:
        """The blob's bytes, CRC included (not checked: see ``check``)."""
        body = bytearray()
        for j in self.joints:
            body += JOINT.pack(j.servo_id, int(j.reverse), j.zero, j.low, j.high)
        for s in self.segments:
            body += _pack_segment(s)
        for block in self.blocks:
            for row in block:
                body += PERIODIC_JOINT.pack(*row)
        for frame in self.frames:
            body += struct.pack(f"<{len(frame)}H", *frame)
        header = HEADER.pack(
            MAGIC,
            lib.PROG_VERSION,
            len(self.joints),
            len(self.segments),
            len(self.blocks),
            self.period_ms,
            len(self.frames),
            0,
        )
        blob = bytearray(header + body)
        struct.pack_into("<I", blob, lib.PROG_CRC_OFFSET, table_crc(bytes(blob)))
        return bytes(blob)

    @classmethod
    def decode(cls, data: bytes) -> Program:
        """The program in ``data``; ProgramError (with the controller's code) if the
        controller would refuse it."""
        check(data)
        _, _, n_joints, n_segments, n_blocks, period, n_frames, _ = HEADER.unpack_from(data)
        offset = HEADER.size
        joints = []
        for _ in range(n_joints):
            sid, flags, zero, low, high = JOINT.unpack_from(data, offset)
            joints.append(JointRecord(sid, zero, low, high, bool(flags & lib.PROG_JOINT_REVERSE)))
            offset += JOINT.size
        segments = []
        for _ in range(n_segments):
            segments.append(_unpack_segment(data[offset : offset + SEGMENT.size]))
            offset += SEGMENT.size
        blocks = []
        for _ in range(n_blocks):
            rows = [PERIODIC_JOINT.unpack_from(data, offset + i * 6) for i in range(n_joints)]
            blocks.append(tuple(rows))
            offset += PERIODIC_JOINT.size * n_joints
        frames = [
            struct.unpack_from(f"<{n_joints}H", data, offset + 2 * n_joints * f)
            for f in range(n_frames)
        ]
        return cls(period, tuple(joints), tuple(segments), tuple(blocks), tuple(frames))


def _pack_segment(s: Segment) -> bytes:
    if isinstance(s, TableSegment):
        return struct.pack(
            "<BBHHHHH", lib.PROG_KIND_TABLE, 0, s.first, s.count, s.repetitions, 0, 0
        )
    if isinstance(s, SerpenoidSegment):
        fields = (s.amp_mrad, s.omega_mrad_s, s.delta_mrad, s.phi0_mrad, s.steps)
        return struct.pack("<BBHhhhH", lib.PROG_KIND_SERPENOID, 0, *fields)
    return struct.pack(
        "<BBHhHHH", lib.PROG_KIND_PERIODIC, 0, s.block, s.omega_mrad_s, s.steps, 0, 0
    )


def _unpack_segment(raw: bytes) -> Segment:
    kind = raw[0]
    if kind == lib.PROG_KIND_TABLE:
        first, count, reps, _, _ = struct.unpack_from("<HHHHH", raw, 2)
        return TableSegment(first, count, reps)
    if kind == lib.PROG_KIND_SERPENOID:
        return SerpenoidSegment(*struct.unpack_from("<HhhhH", raw, 2))
    block, omega, steps, _, _ = struct.unpack_from("<HhHHH", raw, 2)
    return PeriodicSegment(block, omega, steps)


def check(data: bytes, capacity: int = CAPACITY) -> None:
    """ProgramError with the controller's code and advice unless the controller's own check
    (prog_validate, the C core) accepts ``data``."""
    bad = ffi.new("uint8_t *")
    code = lib.prog_validate(data, len(data), capacity, bad)
    if code != lib.CTL_UPLOAD_RESULT_OK:
        in_segments = code in (
            lib.CTL_UPLOAD_RESULT_PROGRAM_BAD_SEGMENT,
            lib.CTL_UPLOAD_RESULT_PROGRAM_OUT_OF_RANGE,
            lib.CTL_UPLOAD_RESULT_PROGRAM_TOO_FAST,
        )
        raise refusal(code, bad[0] if in_segments else None)


def is_program(data: bytes) -> bool:
    """Whether ``data`` starts like a program (rather than a gait table or limits)."""
    return data[:4] == MAGIC


__all__ = [
    "Block",
    "JointRecord",
    "PeriodicSegment",
    "Program",
    "ProgramError",
    "SerpenoidSegment",
    "Segment",
    "TableSegment",
    "check",
    "is_program",
]
