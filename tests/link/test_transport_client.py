"""DxlClient against a Protocol 1.0 device on the far end of a real pseudo-terminal.

The responder thread reads the instruction stream from the pty's master side with the
real parser and answers with packets built by ``snakebot.formats.protocol``; each test scripts
what goes wrong on the wire (an echo, a late stale reply, a damaged checksum, error bits).

Timeouts: clients that expect an answer use a large latency margin, so a slow, shared
machine never turns a reply into a timeout (the client returns as soon as the reply is
in, so the margin costs nothing); tests that expect silence use a small one.
"""

from __future__ import annotations

import dataclasses
import os
import select
import threading
import tty
from collections.abc import Callable, Iterator

import pytest
import serial

from snakebot.formats import protocol
from snakebot.formats.protocol import (
    BROADCAST_ID,
    CorruptPacket,
    DxlTimeout,
    ErrorFlags,
    Instruction,
    Packet,
    PacketParser,
    ProtocolError,
    ServoError,
)
from snakebot.link.transport import DxlClient

PRESENT_POSITION = 36
GOAL_POSITION = 30
TEMPERATURE = 43
GENEROUS_S = 2.0  # latency margin when a reply is expected
SHORT_S = 0.05  # latency margin when silence is expected


def ax12_table(servo_id: int) -> bytearray:
    table = bytearray(50)
    table[0:2] = (12).to_bytes(2, "little")  # model number: AX-12A
    table[3] = servo_id
    table[16] = 2  # Status Return Level
    table[PRESENT_POSITION : PRESENT_POSITION + 2] = (0x1FF).to_bytes(2, "little")
    table[TEMPERATURE] = 37
    return table


class PtyServos:
    """AX-12-like devices behind a pseudo-terminal: a thread answers on the master side.

    ``respond(packet)`` returns the byte chunks to write back, in order; it defaults to
    ``answer`` (what healthy servos would send) and tests replace it to script faults.
    """

    def __init__(self, ids: tuple[int, ...] = (1,), echo: bool = False) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.tables = {i: ax12_table(i) for i in ids}
        self.echo = echo
        self.received: list[Packet] = []
        self.respond: Callable[[Packet], list[bytes]] = self.answer
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def answer(self, packet: Packet) -> list[bytes]:
        """The status a healthy AX-12 sends for ``packet`` (nothing for broadcast)."""
        table = self.tables.get(packet.id)
        if packet.code == Instruction.SYNC_WRITE:
            address, length = packet.params[0], packet.params[1]
            body = packet.params[2:]
            for k in range(0, len(body), length + 1):
                target = self.tables.get(body[k])
                if target is not None:
                    target[address : address + length] = body[k + 1 : k + 1 + length]
            return []
        if table is None:
            return []
        if packet.code == Instruction.READ:
            address, length = packet.params
            return [protocol.status(packet.id, 0, bytes(table[address : address + length]))]
        if packet.code == Instruction.WRITE:
            address = packet.params[0]
            data = packet.params[1:]
            table[address : address + len(data)] = data
            return [protocol.status(packet.id)] if table[16] >= 2 else []
        if packet.code == Instruction.PING:
            return [protocol.status(packet.id)]
        return [protocol.status(packet.id, ErrorFlags.INSTRUCTION)]

    def instructions(self, code: int) -> list[Packet]:
        return [p for p in self.received if p.code == code]

    def _run(self) -> None:
        parser = PacketParser()
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.02)
            if not ready:
                continue
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            for event in parser.feed(data):
                if not isinstance(event, Packet):
                    continue
                self.received.append(event)
                if event.id == BROADCAST_ID:  # applied by every servo, answered by none
                    self.answer(event)
                    replies = []
                else:
                    replies = self.respond(event)
                chunks = ([event.encode()] if self.echo else []) + replies
                for chunk in chunks:
                    os.write(self.master, chunk)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        os.close(self.master)
        os.close(self.slave)


@pytest.fixture
def servos() -> Iterator[PtyServos]:
    bus = PtyServos(ids=(1, 2))
    yield bus
    bus.close()


@pytest.fixture
def echo_servos() -> Iterator[PtyServos]:
    bus = PtyServos(ids=(1, 2), echo=True)
    yield bus
    bus.close()


@pytest.fixture
def connect() -> Iterator[Callable[..., DxlClient]]:
    clients: list[DxlClient] = []

    def make(bus: PtyServos, **kwargs: object) -> DxlClient:
        kwargs.setdefault("latency_s", GENEROUS_S)
        kwargs.setdefault("margin_s", 0.0)
        client = DxlClient(bus.path, **kwargs)  # type: ignore[arg-type]
        clients.append(client)
        return client

    yield make
    for client in clients:
        client.close()


def with_latency(client: DxlClient, latency_s: float) -> None:
    client.timing = dataclasses.replace(client.timing, latency_s=latency_s)


# -- ordinary traffic -------------------------------------------------------------------


def test_ping_read_write_round_trip(servos, connect):
    bus = connect(servos)
    status = bus.ping(1)
    assert (status.id, status.error, status.params) == (1, ErrorFlags(0), b"")
    assert bus.model_number(2) == 12
    assert bus.read_u16(1, PRESENT_POSITION) == 0x1FF
    assert bus.read_u8(1, TEMPERATURE) == 37
    bus.write_u16(1, GOAL_POSITION, 700)
    assert servos.tables[1][GOAL_POSITION : GOAL_POSITION + 2] == (700).to_bytes(2, "little")
    assert bus.read_u16(1, GOAL_POSITION) == 700
    bus.write_u8(2, 25, 1)
    assert bus.read(2, 25, 1) == b"\x01"
    assert bus.echo is False  # auto-detected: this bus does not echo


def test_context_manager_closes_the_port_it_opened(servos):
    with DxlClient(servos.path, latency_s=GENEROUS_S) as bus:
        assert bus.read_u8(1, TEMPERATURE) == 37
        port = bus.port
    assert not port.is_open


def test_given_port_is_used_and_left_open(servos):
    port = serial.serial_for_url(servos.path, baudrate=57600, timeout=0)
    try:
        with DxlClient(port, latency_s=GENEROUS_S) as bus:
            assert bus.baudrate == 57600
            assert bus.read_u16(1, PRESENT_POSITION) == 0x1FF
        assert port.is_open
    finally:
        port.close()


# -- half-duplex echo -------------------------------------------------------------------


@pytest.mark.parametrize("echo", ["auto", True])
def test_echo_is_skipped_and_the_real_reply_read(echo_servos, connect, echo):
    bus = connect(echo_servos, echo=echo)
    assert bus.read_u16(1, PRESENT_POSITION) == 0x1FF
    assert bus.echo is True
    bus.write_u16(2, GOAL_POSITION, 321)
    assert bus.read_u16(2, GOAL_POSITION) == 321
    assert bus.ping(1).id == 1


def test_echoed_read_looks_like_a_reply_to_a_naive_client():
    # Why this matters: READ(1, 36, 2) parsed as a status packet comes from ID 1 with two
    # data bytes, exactly the shape of the reply (this is where DynamixelSDK goes wrong).
    (echo,) = PacketParser().feed(protocol.read(1, PRESENT_POSITION, 2))
    assert (echo.id, len(echo.params)) == (1, 2)


@pytest.mark.parametrize("echo", ["auto", True])
def test_echoed_read_is_never_taken_for_the_reply(echo_servos, connect, echo):
    bus = connect(echo_servos, echo=echo, latency_s=SHORT_S, retries=1)
    echo_servos.respond = lambda packet: []  # the servo stays silent; only the echo comes
    with pytest.raises(DxlTimeout) as info:
        bus.read_u16(1, PRESENT_POSITION)
    assert "READ to servo 1" in str(info.value)
    assert len(echo_servos.instructions(Instruction.READ)) == 2  # first try + 1 retry
    assert bus.echo is True


def test_auto_echo_takes_a_reply_identical_to_the_instruction_on_a_quiet_bus(servos, connect):
    # No echo here, and the servo's status is byte for byte the READ: angle-limit bit
    # (0x02 = READ's code) and data 36, 2. Auto mode must not drop it as an "echo".
    bus = connect(servos, latency_s=0.25)
    servos.respond = lambda packet: [protocol.status(1, ErrorFlags.ANGLE_LIMIT, b"\x24\x02")]
    reply = bus.transact(protocol.read(1, PRESENT_POSITION, 2), 1, 2, check=False)
    assert (reply.error, reply.params) == (ErrorFlags.ANGLE_LIMIT, b"\x24\x02")
    assert bus.echo is False
    assert len(servos.instructions(Instruction.READ)) == 1


def test_loop_url_echo_only_bus_times_out_instead_of_returning_the_echo():
    with DxlClient("loop://", latency_s=SHORT_S, retries=0) as bus:
        with pytest.raises(DxlTimeout):
            bus.read(1, PRESENT_POSITION, 2)


def test_echo_off_without_echo_reads_normally(servos, connect):
    bus = connect(servos, echo=False)
    assert bus.read_u16(1, PRESENT_POSITION) == 0x1FF


# -- stale replies ----------------------------------------------------------------------


def test_late_reply_from_other_servo_is_discarded(servos, connect):
    bus = connect(servos)
    answered: list[bytes] = []

    def respond(packet: Packet) -> list[bytes]:
        if packet.id == 2 and not answered:  # servo 2 is slow: its reply comes too late
            answered.append(protocol.status(2, 0, b"\x34\x12"))
            return []
        late, answered[:] = answered[:], []
        return late + servos.answer(packet)

    servos.respond = respond
    with_latency(bus, SHORT_S)
    with pytest.raises(DxlTimeout):
        bus.transact(protocol.read(2, PRESENT_POSITION, 2), 2, 2, retries=0)
    with_latency(bus, GENEROUS_S)
    # The late reply from servo 2 (same length) arrives just before servo 1's reply.
    assert bus.read_u16(1, PRESENT_POSITION) == 0x1FF


def test_late_reply_of_other_length_from_same_servo_is_discarded(servos, connect):
    bus = connect(servos)
    stale = protocol.status(1, 0, b"\x25")  # an earlier 1-byte READ (temperature) answered late

    def respond(packet: Packet) -> list[bytes]:
        return [stale] + servos.answer(packet)

    servos.respond = respond
    assert bus.read_u16(1, PRESENT_POSITION) == 0x1FF


def test_late_reply_before_the_echo_is_discarded_even_if_it_matches(echo_servos, connect):
    bus = connect(echo_servos, echo=True)
    stale = protocol.status(1, 0, b"\x34\x12")  # same ID, same length: only order tells

    echo_servos.echo = False  # the responder writes the stale packet, then the echo itself
    echo_servos.respond = lambda packet: [stale, packet.encode()] + echo_servos.answer(packet)
    assert bus.read_u16(1, PRESENT_POSITION) == 0x1FF


# -- corruption and errors --------------------------------------------------------------


def damaged(packet: bytes) -> bytes:
    return packet[:-1] + bytes(((packet[-1] + 1) & 0xFF,))


def test_corrupt_reply_is_retried(servos, connect):
    bus = connect(servos, latency_s=0.4, retries=2)
    first = []

    def respond(packet: Packet) -> list[bytes]:
        reply = servos.answer(packet)
        if not first:
            first.append(True)
            return [damaged(reply[0])]
        return reply

    servos.respond = respond
    assert bus.read_u16(1, PRESENT_POSITION) == 0x1FF
    assert len(servos.instructions(Instruction.READ)) == 2


def test_persistent_corruption_raises_and_never_returns_a_value(servos, connect):
    bus = connect(servos, latency_s=0.4, retries=2)
    servos.respond = lambda packet: [damaged(r) for r in servos.answer(packet)]
    with pytest.raises(CorruptPacket) as info:
        bus.read_u16(1, PRESENT_POSITION)
    assert "READ to servo 1" in str(info.value)
    assert len(servos.instructions(Instruction.READ)) == 3


def test_reply_of_wrong_length_is_corrupt_not_a_value(servos, connect):
    bus = connect(servos, latency_s=0.1, retries=1)
    servos.respond = lambda packet: [protocol.status(packet.id, 0, b"\x01\x02\x03")]
    with pytest.raises(CorruptPacket, match="3 data bytes where 2 were expected"):
        bus.read(1, PRESENT_POSITION, 2)


def test_the_late_answer_to_an_earlier_request_is_stale_not_misshapen(servos, connect):
    """A servo (or a controller run late by a busy host) that answers a READ after the
    client gave up on it: its reply, with that READ's length, comes while the client waits
    for the next request's. It is skipped as stale: the next reply is taken, and without
    one the error is the timeout it is, not a device that answers with the wrong length
    (`make demo` beside heavy load once blamed the controller that way)."""
    bus = connect(servos, latency_s=0.05, retries=0)
    late: list[bytes] = []

    def respond(packet: Packet) -> list[bytes]:
        if packet.params[1] == 3:  # the first request: answered only later
            late.append(protocol.status(packet.id, 0, b"\x01\x02\x03"))
            return []
        return [late.pop(), *servos.answer(packet)] if late else servos.answer(packet)

    servos.respond = respond
    with pytest.raises(DxlTimeout):
        bus.read(1, PRESENT_POSITION, 3)
    assert bus.read_u16(1, PRESENT_POSITION) == 0x1FF  # the late reply skipped

    def only_late(packet: Packet) -> list[bytes]:
        if packet.params[1] == 3:
            late.append(protocol.status(packet.id, 0, b"\x01\x02\x03"))
            return []
        return [late.pop()] if late else []

    servos.respond = only_late
    with pytest.raises(DxlTimeout):
        bus.read(1, PRESENT_POSITION, 3)
    with pytest.raises(DxlTimeout):  # not CorruptPacket: "3 data bytes where 2 ..."
        bus.read_u16(1, PRESENT_POSITION)


def test_servo_error_raises_at_once_with_flags(servos, connect):
    bus = connect(servos)
    flags = ErrorFlags.OVERHEATING | ErrorFlags.OVERLOAD
    servos.respond = lambda packet: [protocol.status(packet.id, flags, b"\x00\x02")]
    with pytest.raises(ServoError) as info:
        bus.read_u16(1, PRESENT_POSITION)
    assert info.value.id == 1
    assert info.value.flags == flags
    assert "overheating" in str(info.value) and "overload" in str(info.value)
    assert len(servos.instructions(Instruction.READ)) == 1  # no retry on servo errors


def test_ping_without_check_reports_flags(servos, connect):
    # A PING answered with bit 0 equals the PING itself: the first one costs an echo probe.
    bus = connect(servos, latency_s=0.25)
    servos.respond = lambda packet: [protocol.status(packet.id, ErrorFlags.INPUT_VOLTAGE)]
    assert bus.ping(1, check=False).error == ErrorFlags.INPUT_VOLTAGE
    with pytest.raises(ServoError):
        bus.ping(1)


def test_timeout_message_names_id_instruction_timeout_and_baud(servos, connect):
    bus = connect(servos, latency_s=SHORT_S, retries=0)
    with pytest.raises(DxlTimeout) as info:
        bus.ping(9)
    text = str(info.value)
    timeout_ms = bus.timing.reply_timeout_s(6, 0) * 1e3
    for part in ("PING to servo 9", f"{timeout_ms:.1f} ms", "1000000 baud", "powered"):
        assert part in text


# -- instructions without a reply -------------------------------------------------------


@pytest.fixture
def loop_port() -> Iterator[serial.SerialBase]:
    # loop:// returns what is written: whatever the client leaves unread, it did not wait for.
    port = serial.serial_for_url("loop://", baudrate=1_000_000, timeout=0)
    yield port
    port.close()


def test_sync_write_and_broadcast_do_not_read(loop_port):
    bus = DxlClient(loop_port, latency_s=30.0)  # a wait would hang the test
    bus.sync_write(GOAL_POSITION, 2, {1: b"\x00\x02", 2: b"\xff\x03"})
    assert loop_port.read(100) == protocol.sync_write(
        GOAL_POSITION, 2, {1: b"\x00\x02", 2: b"\xff\x03"}
    )
    bus.write_u16(BROADCAST_ID, GOAL_POSITION, 512)
    assert loop_port.read(100) == protocol.write(BROADCAST_ID, GOAL_POSITION, b"\x00\x02")
    bus.action()
    assert loop_port.read(100) == protocol.action(BROADCAST_ID)


def test_status_return_level_decides_what_waits(loop_port):
    bus = DxlClient(loop_port, latency_s=30.0)
    bus.set_status_return_level(3, 1)
    bus.write_u16(3, GOAL_POSITION, 100)  # level 1: WRITE is not answered
    assert loop_port.read(100) == protocol.write(3, GOAL_POSITION, b"\x64\x00")
    bus.reg_write(3, GOAL_POSITION, b"\x00\x01")
    assert loop_port.read(100) == protocol.reg_write(3, GOAL_POSITION, b"\x00\x01")
    bus.set_status_return_level(3, 0)
    with pytest.raises(ProtocolError, match="Status Return Level 0"):
        bus.read_u8(3, TEMPERATURE)
    assert loop_port.read(100) == b""  # refused before anything was sent


def test_writing_status_return_level_is_tracked(servos, connect):
    bus = connect(servos)
    bus.write_u8(1, 16, 1)  # the servo answers by its new level, so it stays quiet
    assert bus.status_return_level(1) == 1
    bus.write_u16(1, GOAL_POSITION, 400)  # no reply expected now, none waited for
    assert bus.read_u16(1, GOAL_POSITION) == 400  # READ is still answered at level 1
    assert servos.tables[1][16] == 1
    assert bus.status_return_level(2) == 2


def test_sync_write_reaches_servos(servos, connect):
    bus = connect(servos)
    goals = {1: (100).to_bytes(2, "little"), 2: (900).to_bytes(2, "little")}
    bus.sync_write(GOAL_POSITION, 2, goals)
    assert bus.read_u16(1, GOAL_POSITION) == 100
    assert bus.read_u16(2, GOAL_POSITION) == 900


def test_read_from_broadcast_is_refused(servos, connect):
    bus = connect(servos)
    with pytest.raises(ProtocolError, match="broadcast"):
        bus.read(BROADCAST_ID, 0, 2)


def test_values_out_of_range_are_refused(loop_port):
    bus = DxlClient(loop_port)
    with pytest.raises(ValueError):
        bus.write_u16(1, GOAL_POSITION, 70000)
    with pytest.raises(ValueError):
        bus.write_u8(1, 25, -1)


def test_retry_count_comes_from_the_environment(servos, monkeypatch):
    monkeypatch.setenv("SNAKEBOT_RETRIES", "3")
    servos.respond = lambda packet: []
    with DxlClient(servos.path, latency_s=SHORT_S) as bus, pytest.raises(DxlTimeout) as info:
        bus.read_u8(1, TEMPERATURE)
    assert "4 attempts" in str(info.value)
    assert len(servos.instructions(Instruction.READ)) == 4
