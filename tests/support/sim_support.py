"""Helpers for the emulator tests: raw Protocol 1.0 exchanges with an in-process bus."""

from __future__ import annotations

from snakebot.formats.protocol import Packet, PacketParser, Rejected
from snakebot.sim.bus.bus import Bus
from snakebot.sim.servo.fast import VirtualServo

REPLY_WAIT_S = 0.01  # bus time: longer than any reply at 1 Mbps with the default delay


def make_bus(*ids: int, **kwargs) -> Bus:
    """A 1 Mbps bus with factory-fresh AX-12As at ``ids`` (default: one at ID 1)."""
    model = kwargs.pop("model", "AX-12A")
    ideal = kwargs.pop("ideal", False)
    return Bus([VirtualServo(i, model, ideal=ideal) for i in (ids or (1,))], **kwargs)


def exchange(bus: Bus, packet: bytes, wait: float = REPLY_WAIT_S) -> list[Packet | Rejected]:
    """Send ``packet`` as the master, run the bus ``wait`` seconds, parse what came back."""
    bus.master_flush_input()
    bus.master_write(packet)
    bus.run_until(bus.now + wait)
    return PacketParser().feed(bus.master_read(1 << 16))


def reply(bus: Bus, packet: bytes, wait: float = REPLY_WAIT_S) -> Packet:
    """The one status packet ``packet`` gets."""
    events = exchange(bus, packet, wait)
    assert len(events) == 1 and isinstance(events[0], Packet), events
    return events[0]


def hear(bus: Bus, stream: list[tuple[float, bytes]]) -> list[tuple[float, int]]:
    """Send each packet of ``stream`` as the master, then run the bus for its wait:
    every byte the master gets and the bus time it arrived, one byte at a time."""
    heard = []
    for wait, packet in stream:
        bus.master_write(packet)
        end = bus.now + wait
        while bus.run_until_master_data(end):
            heard += [(bus.now, b) for b in bus.master_read(1)]
    return heard
