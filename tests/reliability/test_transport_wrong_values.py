"""The client does not return wrong values as right (issue #17): a status with the
CHECKSUM or INSTRUCTION bit makes it send the instruction again; a value outside its
register's range is read again and then refused; ``read_confirmed`` needs two equal
replies. A scripted AX-12 answers on the far end of a real pseudo-terminal."""

from __future__ import annotations

import os
import select
import threading
import tty
from collections.abc import Callable, Iterator
from types import SimpleNamespace

import pytest

from snakebot.formats import protocol
from snakebot.formats.protocol import (
    CorruptPacket,
    ErrorFlags,
    Instruction,
    Packet,
    PacketParser,
    ServoError,
)
from snakebot.formats.protocol.control_table import ControlTable
from snakebot.link.bus.calibrate import read_zero_ticks
from snakebot.link.transport import DxlClient

PUNCH = ControlTable.for_model("AX-12A").by_name("Punch")
LED = ControlTable.for_model("AX-12A").by_name("LED")

Script = Callable[[Packet, int], bytes]
"""What the servo sends for the n-th instruction (counting from 0)."""


class ScriptedServo:
    """Answers each instruction heard on a pty with what ``script`` says."""

    def __init__(self, script: Script) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.script = script
        self.heard: list[Packet] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        parser = PacketParser()
        while not self._stop.is_set():
            if not select.select([self.master], [], [], 0.02)[0]:
                continue
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            for event in parser.feed(data):
                if isinstance(event, Packet):
                    self.heard.append(event)
                    os.write(self.master, self.script(event, len(self.heard) - 1))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        os.close(self.master)
        os.close(self.slave)


@pytest.fixture
def scripted() -> Iterator[Callable[[Script], tuple[ScriptedServo, DxlClient]]]:
    made: list[tuple[ScriptedServo, DxlClient]] = []

    def make(script: Script) -> tuple[ScriptedServo, DxlClient]:
        servo = ScriptedServo(script)
        client = DxlClient(servo.path, echo=False, retries=2, latency_s=1.0, margin_s=0.0)
        made.append((servo, client))
        return servo, client

    yield make
    for servo, client in made:
        client.close()
        servo.close()


def punch(value: int) -> bytes:
    return protocol.status(1, 0, value.to_bytes(2, "little"))


@pytest.mark.parametrize("flag", [ErrorFlags.CHECKSUM, ErrorFlags.INSTRUCTION])
def test_a_damaged_instruction_is_sent_again(scripted, flag):
    servo, client = scripted(lambda p, n: protocol.status(1, flag if n < 2 else 0))
    client.write(1, LED.address, b"\x01")
    assert [p.code for p in servo.heard] == [Instruction.WRITE] * 3


def test_a_damaged_instruction_every_time_is_a_servo_error(scripted):
    servo, client = scripted(lambda p, n: protocol.status(1, ErrorFlags.CHECKSUM))
    with pytest.raises(ServoError) as info:
        client.write(1, LED.address, b"\x01")
    assert info.value.flags == ErrorFlags.CHECKSUM
    assert len(servo.heard) == 3


def test_other_error_bits_are_not_resent(scripted):
    servo, client = scripted(lambda p, n: protocol.status(1, ErrorFlags.OVERLOAD))
    with pytest.raises(ServoError):
        client.write(1, LED.address, b"\x01")
    assert len(servo.heard) == 1


def test_a_value_outside_its_range_is_read_again(scripted):
    # Punch is 32..1023: 5 is a reply damaged in a way the 8-bit checksum missed.
    servo, client = scripted(lambda p, n: punch(5 if n == 0 else 300))
    assert client.read(1, PUNCH.address, 2) == (300).to_bytes(2, "little")
    assert len(servo.heard) == 2


def test_a_value_always_outside_its_range_is_refused(scripted):
    servo, client = scripted(lambda p, n: punch(5))
    with pytest.raises(CorruptPacket, match="Punch = 5, outside its range 32..1023"):
        client.read(1, PUNCH.address, 2)
    assert len(servo.heard) == 3


@pytest.mark.parametrize(
    ("name", "value"),
    [("Present Temperature", 200), ("Present Position", 1500), ("Present Speed", 1 << 11)],
)
def test_a_read_only_value_outside_what_the_servo_can_hold_is_refused(scripted, name, value):
    # Read-only registers have no write range: these ranges come from the description's
    # read ranges and encodings. A damaged telemetry value used to pass.
    reg = ControlTable.for_model("AX-12A").by_name(name)
    reply = protocol.status(1, 0, value.to_bytes(reg.size, "little"))
    servo, client = scripted(lambda p, n: reply)
    with pytest.raises(CorruptPacket, match=f"{name} = {value}, outside its range"):
        client.read(1, reg.address, reg.size)
    assert len(servo.heard) == 3


def test_range_checks_can_be_turned_off(scripted):
    servo = ScriptedServo(lambda p, n: punch(5))
    client = DxlClient(servo.path, echo=False, latency_s=1.0, check_ranges=False)
    try:
        assert client.read(1, PUNCH.address, 2) == (5).to_bytes(2, "little")
    finally:
        client.close()
        servo.close()


def test_a_confirmed_read_needs_two_equal_replies(scripted):
    values = [100, 200, 200]
    servo, client = scripted(lambda p, n: punch(values[min(n, 2)]))
    assert client.read_confirmed(1, PUNCH.address, 2) == (200).to_bytes(2, "little")
    assert len(servo.heard) == 3


def test_a_confirmed_read_that_never_agrees_is_refused(scripted):
    servo, client = scripted(lambda p, n: punch(100 + n))
    with pytest.raises(CorruptPacket, match="different values"):
        client.read_confirmed(1, PUNCH.address, 2)


def test_a_range_error_for_data_in_range_is_sent_again(scripted):
    # LED takes 0..1: a RANGE error for 1 means the servo heard something else.
    servo, client = scripted(lambda p, n: protocol.status(1, ErrorFlags.RANGE if n == 0 else 0))
    client.write(1, LED.address, b"\x01")
    assert len(servo.heard) == 2


def test_a_range_error_for_data_out_of_range_is_reported_at_once(scripted):
    servo, client = scripted(lambda p, n: protocol.status(1, ErrorFlags.RANGE))
    with pytest.raises(ServoError):
        client.write(1, LED.address, b"\x07")
    assert len(servo.heard) == 1


def test_calibration_saves_a_zero_tick_only_when_two_reads_agree(scripted):
    # The first Present Position reply is damaged within the range (700 for 500): it
    # must not become the zero tick written to the robot file.
    present = ControlTable.for_model("AX-12A").by_name("Present Position")
    positions = iter([700, 500, 500])

    def script(p: Packet, n: int) -> bytes:
        if p.code == Instruction.READ and p.params[0] == present.address:
            return protocol.status(1, 0, next(positions).to_bytes(2, "little"))
        if p.code == Instruction.READ:  # the model number and firmware: an AX-12A
            return protocol.status(1, 0, bytes([12, 0, 24])[: p.params[1]])
        return protocol.status(1, 0)  # PING, the torque-off WRITE

    servo, client = scripted(script)
    robot = SimpleNamespace(name="one", joints=[SimpleNamespace(servo_id=1)])
    assert read_zero_ticks(client, robot) == {1: 500}
