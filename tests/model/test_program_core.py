"""Controller programs in the C core (firmware/core/prog_run.c, through cffi): the
fixed-point stepping sends the host's floating-point prediction within one tick at every
step, joints stay continuous across segment boundaries, and the controller's check refuses
what it cannot play (protocol/program.md)."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from snakebot.core import ffi, lib
from snakebot.facts.devices import ax12
from snakebot.formats.program import (
    JointRecord,
    PeriodicSegment,
    Program,
    ProgramError,
    SerpenoidSegment,
    TableSegment,
    check,
)
from snakebot.model.program_goals import TICKS_PER_MRAD, predict


def c_goals(program: Program) -> np.ndarray:
    """goals[step, joint] the C core sends, stepping one program step at a time."""
    blob = program.encode()
    n = len(program.joints)
    cursor = ffi.new("prog_cursor *")
    goals = ffi.new(f"uint16_t[{n}]")
    lib.prog_start(cursor)
    out = np.empty((program.total_steps, n), dtype=np.int64)
    for step in range(program.total_steps):
        lib.prog_goals(blob, cursor, 0, goals)
        out[step] = list(goals)
        running = lib.prog_advance(blob, cursor, 1)
        assert running == (step + 1 < program.total_steps)
    return out


def joints(n: int, reverse: tuple[bool, ...] | None = None) -> tuple[JointRecord, ...]:
    flags = reverse or tuple(k % 2 == 1 for k in range(n))
    return tuple(JointRecord(k + 1, 512, 60, 964, flags[k]) for k in range(n))


@st.composite
def programs(draw: st.DrawFn) -> Program:
    n = draw(st.integers(1, 6))
    period = draw(st.sampled_from([5, 10, 20, 33, 50]))
    frames = tuple(
        tuple(draw(st.integers(400, 624)) for _ in range(n)) for _ in range(draw(st.integers(0, 6)))
    )
    blocks = tuple(
        tuple(
            (
                draw(st.integers(-150, 150)),
                draw(st.integers(-250, 250)),
                draw(st.integers(-250, 250)),
            )
            for _ in range(n)
        )
        for _ in range(draw(st.integers(0, 2)))
    )
    kinds = ["serpenoid"] + (["table"] if frames else []) + (["periodic"] if blocks else [])
    segments = []
    for _ in range(draw(st.integers(1, 5))):
        kind = draw(st.sampled_from(kinds))
        steps = draw(st.integers(1, 60))
        if kind == "table":
            first = draw(st.integers(0, len(frames) - 1))
            count = draw(st.integers(1, len(frames) - first))
            segments.append(TableSegment(first, count, draw(st.integers(1, 3))))
        elif kind == "periodic":
            omega = draw(st.integers(-8000, 8000))
            segments.append(PeriodicSegment(draw(st.integers(0, len(blocks) - 1)), omega, steps))
        else:
            segments.append(
                SerpenoidSegment(
                    draw(st.integers(0, 700)),
                    draw(st.integers(-8000, 8000)),
                    draw(st.integers(-3142, 3142)),
                    draw(st.integers(-300, 300)),
                    steps,
                )
            )
    return Program(period, joints(n), tuple(segments), blocks, frames)


@settings(max_examples=150, deadline=None)
@given(programs())
def test_c_goals_match_the_host_prediction_within_one_tick(program: Program) -> None:
    try:
        check(program.encode())
    except ProgramError:
        assume(False)
    expected = predict(program)
    got = c_goals(program)
    assert np.abs(got - expected).max() < 1.0 + 1e-9  # within one tick of the exact value
    assert np.abs(got - np.rint(expected)).max() <= 1


def test_segments_continue_where_the_previous_one_would_have_gone() -> None:
    blocks = (((300, 200, 0), (0, 0, 150)),)
    program = Program(
        20,
        joints(2),
        (
            PeriodicSegment(0, 2000, 40),
            SerpenoidSegment(300, 3000, 1000, 0, 50),
            TableSegment(0, 2, 2),
        ),
        blocks,
        ((560, 470), (540, 480)),
    )
    check(program.encode())
    goals = c_goals(program)
    steps = np.abs(np.diff(goals, axis=0))
    # crossing a boundary (after steps 40 and 90) moves no further than the segment before
    # it was moving by itself: no jump to the next segment's own starting point
    for boundary in (39, 89):
        assert (steps[boundary] <= steps[boundary - 8 : boundary].max(axis=0) + 1).all()
    # the table segment plays its frames offset so that it starts where the wave was going
    table = goals[-4:]
    assert (table[1] - table[0]).tolist() == [540 - 560, 480 - 470]
    assert (table[2] == table[0]).all()


def test_the_program_ends_on_its_last_step() -> None:
    program = Program(10, joints(1), (SerpenoidSegment(200, 1000, 0, 0, 7),))
    blob = program.encode()
    cursor = ffi.new("prog_cursor *")
    lib.prog_start(cursor)
    assert lib.prog_tick(blob, cursor, 35, 256)  # 3 steps, 5 ms kept
    assert (cursor.step, cursor.acc_q8) == (3, 5 * 256)
    assert lib.prog_tick(blob, cursor, 10, 128)  # at half speed: 5 ms more, one step
    assert (cursor.step, cursor.acc_q8) == (4, 0)
    assert not lib.prog_tick(blob, cursor, 100, 256)
    assert (cursor.step, cursor.done) == (6, 1)


def refusal_code(program: Program) -> int:
    with pytest.raises(ProgramError) as caught:
        check(program.encode())
    assert caught.value.code is not None
    return caught.value.code


def test_amplitude_plus_offset_beyond_the_limits_is_refused() -> None:
    # joint limits 60..964 around 512: 452 ticks of room on each side
    room_mrad = 452 / TICKS_PER_MRAD
    fits = SerpenoidSegment(int(room_mrad) - 305, 1000, 0, 300, 10)
    check(Program(20, joints(3), (fits,)).encode())
    wide = SerpenoidSegment(int(room_mrad) - 295, 1000, 0, 300, 10)
    assert (
        refusal_code(Program(20, joints(3), (wide,))) == lib.CTL_UPLOAD_RESULT_PROGRAM_OUT_OF_RANGE
    )


def test_a_ramp_that_walks_out_of_range_is_refused() -> None:
    block = ((1000, 0, 0),)  # 1 rad/s: 452 ticks take ~2.3 s
    short = Program(20, joints(1), (PeriodicSegment(0, 0, 100),), (block,))
    check(short.encode())
    long = Program(20, joints(1), (PeriodicSegment(0, 0, 150),), (block,))
    assert refusal_code(long) == lib.CTL_UPLOAD_RESULT_PROGRAM_OUT_OF_RANGE


def test_motion_faster_than_the_servo_is_refused() -> None:
    # the servo's no-load speed, mrad/s, from its description
    limit = round(ax12().max_speed_rpm * 2 * math.pi / 60 * 1000)
    ok = SerpenoidSegment(1000, limit, 0, 0, 10)
    check(Program(20, joints(1), (ok,)).encode())
    fast = SerpenoidSegment(1000, limit + 1, 0, 0, 10)
    assert refusal_code(Program(20, joints(1), (fast,))) == lib.CTL_UPLOAD_RESULT_PROGRAM_TOO_FAST
    block = ((limit - 500, 100, 0),)
    periodic = Program(20, joints(1), (PeriodicSegment(0, 5001, 10),), (block,))
    assert refusal_code(periodic) == lib.CTL_UPLOAD_RESULT_PROGRAM_TOO_FAST


def test_malformed_blobs_are_refused_with_their_code() -> None:
    program = Program(20, joints(2), (TableSegment(0, 1),), frames=((500, 500),))
    blob = bytearray(program.encode())
    check(bytes(blob))
    assert refusal_code(Program(20, joints(2), (TableSegment(0, 2),), frames=((500, 500),))) == (
        lib.CTL_UPLOAD_RESULT_PROGRAM_BAD_SEGMENT
    )
    assert refusal_code(Program(0, joints(2), (TableSegment(0, 1),), frames=((500, 500),))) == (
        lib.CTL_UPLOAD_RESULT_PROGRAM_BAD_PERIOD
    )
    assert refusal_code(Program(20, joints(2), (TableSegment(0, 1),), frames=((10, 500),))) == (
        lib.CTL_UPLOAD_RESULT_PROGRAM_FRAME_OUT_OF_LIMITS
    )
    for data, code in (
        (blob[:-1], lib.CTL_UPLOAD_RESULT_PROGRAM_TRUNCATED),
        (blob + b"\0", lib.CTL_UPLOAD_RESULT_PROGRAM_TRAILING_BYTES),
        (b"SNKG" + blob[4:], lib.CTL_UPLOAD_RESULT_PROGRAM_BAD_MAGIC),
        (blob[:16] + bytes([blob[16] ^ 1]) + blob[17:], lib.CTL_UPLOAD_RESULT_PROGRAM_CRC_MISMATCH),
    ):
        with pytest.raises(ProgramError) as caught:
            check(bytes(data))
        assert caught.value.code == code
        assert lib.prog_validate(bytes(data), len(data), lib.CTL_MAX_TABLE_BYTES, ffi.NULL) == code


def test_a_program_larger_than_the_buffer_is_refused() -> None:
    frames = lib.CTL_MAX_TABLE_BYTES // (2 * 4) + 1  # 4 joints' frames alone pass the buffer
    program = Program(20, joints(4), (TableSegment(0, 1),), frames=((500,) * 4,) * frames)
    assert refusal_code(program) == lib.CTL_UPLOAD_RESULT_PROGRAM_TOO_BIG


def test_encode_decode_round_trip() -> None:
    program = Program(
        25,
        joints(3),
        (
            PeriodicSegment(0, -1500, 9),
            SerpenoidSegment(100, -700, -500, -20, 4),
            TableSegment(0, 1, 5),
        ),
        (((1, -2, 3), (4, 5, -6), (-7, 8, 9)),),
        ((510, 520, 530),),
    )
    blob = program.encode()
    assert Program.decode(blob) == program
    assert struct.unpack_from("<I", blob, 12)[0] == lib.gt_crc(blob, len(blob))
