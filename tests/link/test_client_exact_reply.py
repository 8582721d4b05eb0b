"""The client's shortcut for a reply that arrives whole in one read: it must accept only
the exact status packet it waits for and leave everything else to the parser, with the
same outcome as before (real pseudo-terminal, a scripted device thread)."""

from __future__ import annotations

import dataclasses
import os
import threading
import time
import tty
from collections.abc import Callable, Iterator

import pytest

from snakebot.formats import protocol
from snakebot.formats.protocol import (
    CorruptPacket,
    DxlTimeout,
    ErrorFlags,
    Packet,
    PacketParser,
    ServoError,
)
from snakebot.link.transport import DxlClient

POSITION = 36
VALUE = 0x1FF


class ScriptedServo:
    """Answers the n-th instruction with ``script(n)``: byte chunks written in order."""

    def __init__(self, script: Callable[[int], list[bytes]]) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.script = script
        self.heard = 0
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        parser = PacketParser()
        while True:
            try:
                data = os.read(self.master, 256)
            except OSError:
                return
            for event in parser.feed(data):
                if isinstance(event, Packet):
                    self.heard += 1  # before answering: the client may look at once
                    for chunk in self.script(self.heard - 1):
                        os.write(self.master, chunk)

    def close(self) -> None:
        os.close(self.master)
        os.close(self.slave)
        self._thread.join(timeout=5)


def good(servo_id: int = 1, value: int = VALUE) -> bytes:
    return protocol.status(servo_id, 0, value.to_bytes(2, "little"))


@pytest.fixture
def servo() -> Iterator[Callable[[Callable[[int], list[bytes]]], DxlClient]]:
    made: list[tuple[ScriptedServo, DxlClient]] = []

    def make(script: Callable[[int], list[bytes]], echo: bool = False) -> DxlClient:
        device = ScriptedServo(script)
        client = DxlClient(device.path, echo=echo, latency_s=0.5, margin_s=0.0, retries=1)
        client.device_under_test = device  # type: ignore[attr-defined]
        made.append((device, client))
        return client

    yield make
    for device, client in made:
        client.close()
        device.close()


def test_a_whole_reply_is_read_in_one_transaction(servo):
    client = servo(lambda n: [good()])
    assert client.read_u16(1, POSITION) == VALUE
    assert client.device_under_test.heard == 1


def test_a_stray_leading_byte_leaves_the_reply_to_the_parser(servo):
    # As long as the reply, but shifted by one byte: not the packet, yet the packet
    # follows; the parser finds it in the same attempt (no resend).
    client = servo(lambda n: [b"\x00" + good()])
    assert client.read_u16(1, POSITION) == VALUE
    assert client.device_under_test.heard == 1


def test_a_same_sized_reply_from_another_servo_is_not_taken(servo):
    client = servo(lambda n: [good(servo_id=2, value=0x200), good()])
    assert client.read_u16(1, POSITION) == VALUE
    assert client.device_under_test.heard == 1


def test_a_bad_checksum_of_the_right_size_is_resent(servo):
    def script(n: int) -> list[bytes]:
        reply = bytearray(good())
        if n == 0:
            reply[-1] ^= 0x01
        return [bytes(reply)]

    client = servo(script)
    assert client.read_u16(1, POSITION) == VALUE
    assert client.device_under_test.heard == 2


def test_bad_checksums_every_time_are_corrupt_not_a_value(servo):
    def script(n: int) -> list[bytes]:
        reply = bytearray(good())
        reply[5] ^= 0x10  # the data changed, the checksum not
        return [bytes(reply)]

    client = servo(script)
    with pytest.raises(CorruptPacket):
        client.read_u16(1, POSITION)


def test_a_whole_reply_with_an_alarm_bit_raises_at_once(servo):
    client = servo(lambda n: [protocol.status(1, ErrorFlags.OVERHEATING, b"\x00\x02")])
    with pytest.raises(ServoError) as info:
        client.read_u16(1, POSITION)
    assert info.value.flags == ErrorFlags.OVERHEATING
    assert client.device_under_test.heard == 1


def test_a_whole_reply_saying_the_instruction_was_damaged_is_resent(servo):
    def script(n: int) -> list[bytes]:
        if n == 0:
            return [protocol.status(1, ErrorFlags.CHECKSUM, b"\x00\x00")]
        return [good()]

    client = servo(script)
    assert client.read_u16(1, POSITION) == VALUE
    assert client.device_under_test.heard == 2


def test_new_timing_applies_to_reads_already_made(servo):
    client = servo(lambda n: [good()] if n == 0 else [])
    assert client.read_u16(1, POSITION) == VALUE  # the READ is made with a 0.5 s latency
    client.timing = dataclasses.replace(client.timing, latency_s=0.01)
    start = time.monotonic()
    with pytest.raises(DxlTimeout):
        client.read_u16(1, POSITION)  # the servo is silent now: 2 attempts of ~11 ms
    # with the old timing the two attempts would have waited 0.5 s each; the bound leaves
    # a loaded machine most of a second to run the new ones
    assert time.monotonic() - start < 0.9
    assert client.device_under_test.heard == 3


READ_POSITION = protocol.read(1, POSITION, 2)


def test_on_an_echoing_bus_the_echo_and_the_reply_are_read_together(servo):
    client = servo(lambda n: [READ_POSITION + good()], echo=True)
    assert client.read_u16(1, POSITION) == VALUE
    assert client.read_u16(1, POSITION) == VALUE
    assert client.device_under_test.heard == 2


def test_on_an_echoing_bus_a_late_echo_after_ours_is_not_the_reply(servo):
    # An earlier instruction whose bytes are those of a clean reply to the READ; heard
    # again after the READ's echo, it is that instruction's late echo, not the answer.
    earlier = protocol.status(1, 0, b"\x00\x02")
    client = servo(lambda n: [earlier] if n == 0 else [READ_POSITION + earlier], echo=True)
    client.send(earlier)
    with pytest.raises(DxlTimeout):
        client.read_u16(1, POSITION)
    assert client.device_under_test.heard == 3  # the earlier one, then the READ twice
