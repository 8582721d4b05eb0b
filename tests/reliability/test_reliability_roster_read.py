"""The bug the fault campaigns and the PC-link fuzzer found (fuzz/regressions/fuzz_pclink/
roster-*-mid-read), checked through the host build of the C core so it stays fixed even
where clang is missing: a telemetry READ in flight when the PC changes the roster.

Before the fix, shrinking the roster mid-READ dropped the READ from the counters (neither
a Bus Read nor a Bus Timeout), and changing the servo ID of the slot being read filed the
old servo's reply under the new one, so the monitor showed one servo's position as
another's."""

from __future__ import annotations

import numpy as np
from ctl_support import CTL, CTL_ID, Device, telemetry_reply

from snakebot.core import ffi, lib
from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import Instruction, PacketParser, write

IDS = (1, 2, 3)


def device_with_read_in_flight() -> tuple[Device, int]:
    """A device with a table (roster 1, 2, 3) whose first tick's telemetry READ has gone
    out and awaits its reply; returns the device and the servo ID being read."""
    dev = Device()
    table = GaitTable(IDS, 100, True, ((300, 700),) * 3, np.full((2, 3), 512, np.uint16))
    assert dev.upload(table.encode()) == 0
    lib.ctl_tick(dev.d, 10)
    out = ffi.new("uint8_t[]", lib.CTL_BUS_TX_MAX)
    reply_len = ffi.new("uint8_t *")
    while True:
        n = lib.ctl_bus_next(dev.d, out, lib.CTL_BUS_TX_MAX, reply_len)
        assert n > 0, "the tick sent no telemetry READ"
        (packet,) = PacketParser().feed(bytes(ffi.buffer(out, n)))
        if packet.code == Instruction.READ:
            assert reply_len[0] == 14
            return dev, packet.id


def counters(dev: Device) -> tuple[int, int]:
    return dev.get("Bus Reads"), dev.get("Bus Timeouts")


def test_a_read_in_flight_when_the_roster_shrinks_is_counted_once():
    dev, sid = device_with_read_in_flight()
    assert counters(dev) == (0, 0)
    assert dev.set("Joint Count", 0) == 0  # the roster empties while the READ waits
    assert counters(dev) == (0, 1)  # ended, as a READ without a usable reply
    reply = telemetry_reply(sid, position=600)
    lib.ctl_bus_rx(dev.d, reply, len(reply))  # the reply still comes
    lib.ctl_bus_rx_done(dev.d)
    assert counters(dev) == (0, 1)  # and is not counted a second time


def test_a_reply_is_never_filed_under_the_servo_that_took_the_slot():
    dev, sid = device_with_read_in_flight()
    assert sid == IDS[0]
    # slot 0 now drives servo 9 instead (a roster WRITE through the servo window)
    record = CTL.servo_window_address
    assert dev.one(write(CTL_ID, record, bytes([9]))).error == 0
    reply = telemetry_reply(sid, position=600, temperature=77)
    done = lib.ctl_bus_rx(dev.d, reply, len(reply))
    lib.ctl_bus_rx_done(dev.d)
    assert not done
    slot0 = dev.servo_window()[0]
    assert slot0["ID"] == 9
    assert slot0["Present Position"] == 0 and slot0["Present Temperature"] == 0
    assert counters(dev) == (0, 1)


def test_an_unchanged_roster_keeps_the_read_in_flight():
    """A commit that keeps the same servos (same roster) must not cut the READ short."""
    dev, sid = device_with_read_in_flight()
    assert dev.set("Joint Count", len(IDS)) == 0  # same roster written again
    reply = telemetry_reply(sid, position=600)
    assert lib.ctl_bus_rx(dev.d, reply, len(reply))
    lib.ctl_bus_rx_done(dev.d)
    assert counters(dev) == (1, 0)
    assert dev.servo_window()[0]["Present Position"] == 600
