"""The emulator's servo (VirtualServo: the hot path in C) against the reference model
(ReferenceServo, all Python): random streams of packets, SYNC_WRITE blocks, loads,
supply changes, power cuts and physics-world reports, applied to one of each, must give
byte-identical status packets, identical control tables and the same motion and heat to
the last bit; and a closed loop on the bus must put the same bytes on the wire at the
same instants."""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sim_support import hear

from snakebot.facts import devices
from snakebot.formats import protocol as P
from snakebot.formats.protocol import Instruction, Packet, Rejected
from snakebot.formats.protocol.instructions import frame
from snakebot.sim.bus.bus import Bus
from snakebot.sim.servo.fast import VirtualServo
from snakebot.sim.servo.reference import ReferenceServo

ROOT = Path(__file__).resolve().parents[2]
AX12 = devices.ax12()
GOAL = AX12.register("Goal Position").address
TABLE_END = 50 + 4  # a little past the table, for READs and writes that run off it


def state(s: ReferenceServo) -> tuple:
    """Everything observable about a servo, exact."""
    return (
        bytes(s.regs.image),
        s.pos,
        s.vel,
        s.temp,
        s.load_fraction,
        s.load_cw,
        s.moving,
        s.overload,
        s.latched,
        s.t,
        s.powered,
        s.id,
        s.baudrate,
        s.return_delay_s,
        int(s.errors),
        s.controller(),
    )


def u16(value: int) -> bytes:
    return value.to_bytes(2, "little")


goals = st.integers(0, 1100).map(u16)
speeds = st.one_of(st.integers(0, 1023), st.integers(1024, 2100)).map(u16)
hot_writes = st.one_of(goals, st.tuples(goals, speeds).map(b"".join))
any_writes = st.tuples(st.integers(0, TABLE_END), st.binary(min_size=0, max_size=8)).map(
    lambda a: bytes((a[0],)) + a[1]
)
writes = st.one_of(hot_writes.map(lambda d: bytes((GOAL,)) + d), any_writes)
reads = st.tuples(st.integers(0, TABLE_END), st.integers(0, 60)).map(bytes)
codes = st.sampled_from([int(i) for i in Instruction] + [0, 7, 200])
dts = st.one_of(st.floats(0.0, 0.005), st.floats(0.0, 0.3), st.just(0.0))


def packets(servo_id: int) -> st.SearchStrategy:
    target = st.sampled_from([servo_id, P.BROADCAST_ID, (servo_id + 1) % 254])
    instruction = st.one_of(
        st.tuples(st.just(int(Instruction.READ)), reads),
        st.tuples(st.sampled_from([int(Instruction.WRITE), int(Instruction.REG_WRITE)]), writes),
        st.tuples(codes, st.binary(max_size=6)),
    )
    return st.tuples(st.just("packet"), dts, target, instruction)


def operations(servo_id: int) -> st.SearchStrategy:
    return st.one_of(
        packets(servo_id),
        packets(servo_id),
        packets(servo_id),
        st.tuples(st.just("sync"), dts, st.one_of(hot_writes, st.binary(max_size=5))),
        st.tuples(st.just("torque"), dts, st.floats(-2.0, 2.0)),
        st.tuples(st.just("supply"), dts, st.floats(5.0, 14.0)),
        st.tuples(st.just("power"), dts, st.booleans()),
        st.tuples(st.just("checksum"), dts, st.sampled_from([int(i) for i in Instruction])),
        st.tuples(
            st.just("world"),
            dts,
            st.tuples(
                st.floats(0.0, 1023.0),
                st.floats(-500.0, 500.0),
                st.floats(0.0, 1.2),
                st.booleans(),
                st.booleans(),
                st.booleans(),
            ),
        ),
    )


def apply(s: ReferenceServo, op: tuple, t: float) -> object:
    kind = op[0]
    if kind == "packet":
        target, (code, params) = op[2], op[3]
        return s.receive(Packet(target, code, bytes(params)), t)
    if kind == "sync":
        return s.sync_write_block(GOAL, op[2], t)
    if kind == "torque":
        return s.set_external_torque(t, op[2])
    if kind == "supply":
        return s.set_supply(t, op[2])
    if kind == "power":
        return s.power_on(t) if op[2] else s.power_off(t)
    if kind == "checksum":
        frame = bytearray(P.ping(s.id))
        frame[4] = op[2]
        frame[-1] ^= 0x55
        return s.receive(Rejected("checksum", bytes(frame)), t)
    return s.set_motion(t, *op[2])


@settings(max_examples=300, deadline=None)
@given(
    servo_id=st.integers(1, 5),
    model=st.sampled_from(["AX-12A", "AX-12W"]),
    position=st.floats(0.0, 1023.0),
    ideal=st.booleans(),
    wheel=st.booleans(),
    data=st.data(),
)
def test_the_c_servo_answers_and_moves_as_the_reference_model(
    servo_id, model, position, ideal, wheel, data
):
    ref = ReferenceServo(servo_id, model, position=position, ideal=ideal)
    fast = VirtualServo(servo_id, model, position=position, ideal=ideal)
    if wheel:
        for s in (ref, fast):
            s.set_register("CCW Angle Limit", 0)
    assert state(fast) == state(ref)
    t = 0.0
    for op in data.draw(st.lists(operations(servo_id), max_size=40)):
        t += op[1]
        assert apply(fast, op, t) == apply(ref, op, t), op
        assert state(fast) == state(ref), op


def bus_frames() -> st.SearchStrategy:
    """Frames a master might send three servos (IDs 1-3, and 4 that nobody has): READs,
    goal and other WRITEs, SYNC_WRITEs, other instructions, now and then a bad checksum."""
    ids = st.sampled_from([1, 2, 3, 4, P.BROADCAST_ID])
    blocks = {2: goals, 4: st.tuples(goals, speeds).map(b"".join)}
    sync = st.sampled_from([2, 4]).flatmap(  # an ID may be named twice: the first counts
        lambda width: st.lists(st.tuples(st.integers(1, 4), blocks[width]), min_size=1).map(
            lambda named: frame(
                P.BROADCAST_ID,
                int(Instruction.SYNC_WRITE),
                bytes((GOAL, width)) + b"".join(bytes((i,)) + d for i, d in named),
            )
        )
    )
    body = st.one_of(
        st.tuples(ids, st.just(int(Instruction.READ)), reads),
        st.tuples(ids, st.just(int(Instruction.WRITE)), writes),
        st.tuples(ids, codes, st.binary(max_size=4)),
    ).map(lambda f: frame(*f))
    damaged = body.map(lambda b: b[:-1] + bytes((b[-1] ^ 0x5A,)))
    return st.one_of(body, body, sync, damaged)


def bus_run(servo_class: type, delay: int, stream: list[tuple[float, bytes]]) -> tuple:
    servos = [servo_class(i) for i in (1, 2, 3)]
    for s in servos:
        s.set_register("Return Delay Time", delay)
    bus = Bus(servos)
    return hear(bus, stream), [state(s) for s in servos]


@settings(max_examples=150, deadline=None)
@given(
    delay=st.sampled_from([0, 5, 250]),
    stream=st.lists(st.tuples(st.floats(0.0, 0.02), bus_frames()), max_size=30),
)
def test_on_the_bus_the_c_servos_answer_the_same_bytes_at_the_same_instants(delay, stream):
    assert bus_run(VirtualServo, delay, stream) == bus_run(ReferenceServo, delay, stream)


def closed_loop(servo_class: type, ticks: int) -> list[tuple[float, bytes]]:
    """A 100 Hz loop on a bus of five servos: SYNC_WRITE goals, READ each one's
    present state, with a load on one servo; every byte the master gets, and when."""
    servos = [servo_class(i) for i in range(1, 6)]
    for s in servos:
        s.set_register("Return Delay Time", 10)
    servos[2].set_external_torque(0.0, 0.4)
    bus = Bus(servos)
    heard = []
    for k in range(ticks):
        goals = {i: u16(512 + round(200 * math.sin(k / 10 + i))) for i in range(1, 6)}
        bus.master_write(P.sync_write(GOAL, 2, goals))
        for i in range(1, 6):
            bus.master_write(P.read(i, 36, 8))
            while bus.run_until_master_data(bus.now + 0.002):
                heard += [(bus.now, b) for b in bus.master_read(1)]
        bus.run_until((k + 1) / 100)
    return heard


def test_a_closed_loop_puts_the_same_bytes_on_the_wire_at_the_same_instants():
    fast = closed_loop(VirtualServo, 60)
    assert len(fast) == 60 * 5 * 14
    assert fast == closed_loop(ReferenceServo, 60)


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_the_c_servo_compiles_clean_with_warnings_as_errors():
    source = ROOT / "host" / "snakebot" / "sim" / "csrc" / "sim_servo.c"
    result = subprocess.run(
        ["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-fsyntax-only"]
        + ["-I", str(ROOT / "firmware" / "core"), str(source)],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize("first", ["snakebot.sim.servo.fast", "snakebot.sim.servo.reference"])
def test_either_servo_module_may_be_imported_first(first):
    code = f"import {first}; from snakebot.sim.servo.fast import VirtualServo; VirtualServo(1)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
