"""Interoperability with ROBOTIS's own dynamixel-sdk (an independent Protocol 1.0
implementation): it sends through a real pseudo-terminal, our parser and builders are
on the other end, byte for byte."""

from __future__ import annotations

import os
import select
import threading

import pytest

from snakebot.formats.protocol import (
    BROADCAST_ID,
    ControlTable,
    Instruction,
    PacketParser,
    action,
    bulk_read,
    reg_write,
    reset,
    status,
    sync_write,
    write,
)

sdk = pytest.importorskip("dynamixel_sdk")

READ_TIMEOUT_S = 5.0


class PatientPort(sdk.PortHandler):
    """The SDK's port with a generous reply timeout: this machine is shared and slow,
    and these tests check bytes, not speed."""

    def setPacketTimeout(self, packet_length):  # noqa: N802 - the SDK's name
        self.setPacketTimeoutMillis(READ_TIMEOUT_S * 1000)


@pytest.fixture
def pty_pair():
    master, slave = os.openpty()
    port = PatientPort(os.ttyname(slave))
    assert port.openPort()
    yield master, port
    port.closePort()
    os.close(slave)
    os.close(master)


def read_exactly(fd: int, n: int) -> bytes:
    data = b""
    while len(data) < n:
        ready, _, _ = select.select([fd], [], [], READ_TIMEOUT_S)
        assert ready, f"only {data.hex(' ')} arrived"
        data += os.read(fd, n - len(data))
    return data


def test_sdk_instructions_are_our_bytes(pty_pair):
    master, port = pty_pair
    handler = sdk.PacketHandler(1.0)
    cases = [
        (lambda: handler.writeTxOnly(port, 1, 12, 2, [0x64, 0xAA]), write(1, 12, b"\x64\xaa")),
        (
            lambda: handler.regWriteTxOnly(port, 7, 30, 2, [0xFF, 0x03]),
            reg_write(7, 30, b"\xff\x03"),
        ),
        (lambda: handler.action(port, BROADCAST_ID), action()),
        (lambda: handler.factoryReset(port, BROADCAST_ID)[0], reset(BROADCAST_ID)),
        (
            lambda: handler.syncWriteTxOnly(port, 30, 2, [1, 0x00, 0x02, 2, 0xFF, 0x03], 6),
            sync_write(30, 2, {1: b"\x00\x02", 2: b"\xff\x03"}),
        ),
        (
            lambda: handler.bulkReadTx(port, [2, 1, 30, 2, 2, 36], 6),
            bulk_read([(1, 30, 2), (2, 36, 2)]),
        ),
    ]
    parser = PacketParser()
    for send, ours in cases:
        assert send() == sdk.COMM_SUCCESS
        wire = read_exactly(master, len(ours))
        assert wire == ours
        assert [p.encode() for p in parser.feed(wire)] == [ours]


class Servos(threading.Thread):
    """Servos answering on the pty's far end, written with our parser and builders over
    ControlTable's factory image. Servo 2 reports overheating + overload on every reply."""

    def __init__(self, master: int, ids: tuple[int, ...]) -> None:
        super().__init__(daemon=True)
        self.master = master
        self.tables = {i: bytearray(ControlTable.for_model("AX-12A").default_image()) for i in ids}
        for i in ids:
            self.tables[i][3] = i
        self.stop = threading.Event()
        self.heard = []

    def answer(self, packet) -> bytes:
        table = self.tables[packet.id]
        error = 0x24 if packet.id == 2 else 0
        if packet.code == Instruction.READ:
            address, length = packet.params
            return status(packet.id, error, bytes(table[address : address + length]))
        if packet.code == Instruction.WRITE:
            address, data = packet.params[0], packet.params[1:]
            table[address : address + len(data)] = data
        return status(packet.id, error)

    def run(self) -> None:
        parser = PacketParser()
        while not self.stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if not ready:
                continue
            for packet in parser.feed(os.read(self.master, 256)):
                self.heard.append(packet)
                if packet.id in self.tables:
                    # Line noise before the reply: the SDK must skip it as we would.
                    os.write(self.master, b"\x00\xff\x12" + self.answer(packet))


@pytest.fixture
def servos(pty_pair):
    master, port = pty_pair
    thread = Servos(master, (1, 2))
    thread.start()
    yield thread, port
    thread.stop.set()
    thread.join()


def test_sdk_reads_our_status_packets(servos):
    thread, port = servos
    handler = sdk.PacketHandler(1.0)
    assert handler.ping(port, 1) == (12, sdk.COMM_SUCCESS, 0)
    assert handler.read1ByteTxRx(port, 1, 5) == (250, sdk.COMM_SUCCESS, 0)
    assert handler.write2ByteTxRx(port, 1, 30, 1000) == (sdk.COMM_SUCCESS, 0)
    assert handler.read2ByteTxRx(port, 1, 30) == (1000, sdk.COMM_SUCCESS, 0)
    assert handler.read1ByteTxRx(port, 2, 3) == (2, sdk.COMM_SUCCESS, 0x24)
    assert [p.code for p in thread.heard] == [
        Instruction.PING,
        Instruction.READ,
        Instruction.READ,
        Instruction.WRITE,
        Instruction.READ,
        Instruction.READ,
    ]
