"""The bus-master schedule: what each control tick puts on the Dynamixel bus, and how
replies (with echoes, noise, corruption or silence) end up in the telemetry mirror."""

from __future__ import annotations

import numpy as np
import pytest
from ctl_support import Device, telemetry_reply
from hypothesis import given
from hypothesis import strategies as st
from player_support import Player

from snakebot.core import ffi, lib
from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import BROADCAST_ID, Instruction, PacketParser, read, sync_write

IDS = (11, 12, 13)
FRAMES = np.array([[512, 512, 512], [600, 450, 300], [700, 400, 250], [650, 420, 260]])


def gait() -> GaitTable:
    return GaitTable(IDS, 20, True, ((200, 824),) * 3, FRAMES)


@pytest.fixture
def dev() -> Device:
    d = Device()
    assert d.upload(gait().encode()) == 0
    return d


def decode_sync_write(packet: bytes) -> dict[int, tuple[int, int]]:
    (p,) = PacketParser().feed(packet)
    assert p.id == BROADCAST_ID and p.code == Instruction.SYNC_WRITE
    assert p.params[:2] == bytes([30, 4])  # Goal Position + Moving Speed
    out = {}
    for at in range(2, len(p.params), 5):
        block = p.params[at : at + 5]
        out[block[0]] = (int.from_bytes(block[1:3], "little"), int.from_bytes(block[3:5], "little"))
    return out


def test_each_tick_sends_goals_then_one_telemetry_read(dev):
    assert dev.command("PLAY") == 0
    reference = Player()
    reference.start_table(gait(), now=0)
    reads = []
    for k in range(12):
        now = 7 * k
        sent = dev.tick(now, {sid: telemetry_reply(sid) for sid in IDS})
        if k == 0:  # torque on for the table's servos first
            assert sent[0] == sync_write(24, 1, {sid: b"\x01" for sid in IDS})
            sent = sent[1:]
        goals, read_packet = sent
        ids, want_goals, want_speeds = reference.tick(now)
        assert decode_sync_write(goals) == {
            int(i): (int(g), int(s)) for i, g, s in zip(ids, want_goals, want_speeds, strict=True)
        }
        reads.append(read_packet)
    # round robin over the roster, READ 8 bytes from Present Position (36)
    assert reads == [read(IDS[k % 3], 36, 8) for k in range(12)]


def test_idle_controller_only_polls(dev):
    sent = dev.tick(0, {})
    assert sent == [read(11, 36, 8)]
    empty = Device()
    assert empty.tick(0, {}) == []  # no roster, nothing to do


def test_telemetry_lands_in_the_servo_window(dev):
    for k in range(3):
        replies = {
            sid: telemetry_reply(
                sid, position=300 + sid, speed=1024 + 5, load=77, voltage=118, temperature=41 + k
            )
            for sid in IDS
        }
        dev.tick(10 * k, replies)
    window = dev.servo_window(0)
    for j, sid in enumerate(IDS):
        w = window[j]
        assert (w["ID"], w["Present Position"], w["Present Speed"]) == (sid, 300 + sid, 1029)
        assert (w["Present Load"], w["Present Voltage"]) == (77, 118)
        assert w["Present Temperature"] == 41 + j
        assert (w["Timeout Count"], w["Error Count"]) == (0, 0)
    assert dev.get("Bus Reads") == 3


def test_echo_and_noise_before_the_reply_are_skipped(dev):
    echo = read(11, 36, 8)  # a one-wire adapter hears our own instruction first
    reply = telemetry_reply(11, position=640)
    dev.tick(0, {11: b"\x00\xff" + echo + b"\xff\xff\x0b" + reply})
    assert dev.servo_window(0)[0]["Present Position"] == 640
    assert dev.get("Bus Timeouts") == 0


def test_corrupt_and_missing_replies_are_counted(dev):
    bad = bytearray(telemetry_reply(11, position=640))
    bad[6] ^= 0x10
    dev.tick(0, {11: bytes(bad)})
    dev.tick(10, {})  # servo 12 silent
    dev.tick(20, {13: telemetry_reply(12)})  # a reply from the wrong servo is no reply
    window = dev.servo_window(0)
    assert [w["Timeout Count"] for w in window[:3]] == [1, 1, 1]
    assert window[0]["Present Position"] == 0
    assert (dev.get("Bus Timeouts"), dev.get("Bus Errors"), dev.get("Bus Reads")) == (3, 1, 0)


class Bus:
    """bus_master alone."""

    def __init__(self, ids: list[int]) -> None:
        self._mem = ffi.new("uint8_t[]", lib.bus_master_size())
        self.b = ffi.cast("bus_master *", self._mem)
        lib.bus_init(self.b)
        self.set_roster(ids)
        self.txn = ffi.new("bus_txn *")
        self.out = ffi.new("uint8_t[]", 128)

    def set_roster(self, ids: list[int]) -> None:
        lib.bus_set_roster(self.b, bytes(ids), len(ids))

    def next(self) -> bytes:
        n = lib.bus_next(self.b, ffi.NULL, ffi.NULL, ffi.NULL, 0, self.out, 128, self.txn)
        return bytes(ffi.buffer(self.out, n))


@given(st.lists(st.integers(1, 14), min_size=1, max_size=6), st.binary(max_size=80))
def test_reply_in_any_chunks_after_any_noise_is_found(cuts, noise):
    bus = Bus([5])
    lib.bus_begin_tick(bus.b)
    assert bus.next() == read(5, 36, 8)
    assert bus.txn.kind == lib.BUS_TXN_READ and bus.txn.reply_len == lib.BUS_REPLY_BYTES
    stream = noise + telemetry_reply(5, position=777)
    done, at = False, 0
    for cut in cuts * 20:
        chunk = stream[at : at + cut]
        at += len(chunk)
        done = lib.bus_rx(bus.b, chunk, len(chunk))
        if done or at >= len(stream):
            break
    if not done:
        rest = stream[at:]
        done = lib.bus_rx(bus.b, rest, len(rest))
    lib.bus_rx_done(bus.b)
    servo = lib.bus_servo_at(bus.b, 0)
    # noise can only hide the reply by containing a valid reply of its own first
    if done and servo.position != 777:
        assert telemetry_reply(5)[:4] in noise
    else:
        assert done and servo.position == 777 and servo.missed == 0


def test_roster_change_keeps_telemetry_of_servos_that_stay():
    bus = Bus([1, 2])
    lib.bus_begin_tick(bus.b)
    bus.next()
    reply = telemetry_reply(1, position=123)
    lib.bus_rx(bus.b, reply, len(reply))
    lib.bus_rx_done(bus.b)
    bus.set_roster([1, 9])
    assert lib.bus_servo_at(bus.b, 0).position == 123
    assert lib.bus_servo_at(bus.b, 1).fresh == 0
    assert lib.bus_servo_at(bus.b, 2) == ffi.NULL


def test_a_forgotten_reply_window_counts_as_a_timeout():
    bus = Bus([3])
    lib.bus_begin_tick(bus.b)
    bus.next()
    lib.bus_begin_tick(bus.b)  # the app never called bus_rx_done
    assert lib.bus_timeouts(bus.b) == 1
    assert lib.bus_servo_at(bus.b, 0).missed == 1


def test_goal_packet_for_eighteen_servos_fits_the_stated_buffer():
    ids = bytes(range(1, 19))
    goals = ffi.new("uint16_t[]", [512] * 18)
    speeds = ffi.new("uint16_t[]", [100] * 18)
    bus = Bus([])
    out = ffi.new("uint8_t[]", lib.CTL_BUS_TX_MAX)
    txn = ffi.new("bus_txn *")
    lib.bus_begin_tick(bus.b)
    n = lib.bus_next(bus.b, ids, goals, speeds, 18, out, lib.CTL_BUS_TX_MAX, txn)
    assert n == lib.CTL_BUS_TX_MAX == 8 + 5 * 18
    assert len(decode_sync_write(bytes(ffi.buffer(out, n)))) == 18
