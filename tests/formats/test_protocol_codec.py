"""The Python codec's API: argument checks, error bits in words, exceptions, decode()."""

from __future__ import annotations

import pickle

import pytest

from snakebot.errors import SnakebotError
from snakebot.formats.protocol import (
    BROADCAST_ID,
    MAX_PACKET_LEN,
    CorruptPacket,
    DxlTimeout,
    ErrorFlags,
    Instruction,
    Packet,
    PacketArgumentError,
    ProtocolError,
    ServoError,
    bulk_read,
    decode,
    encode_packet,
    ping,
    read,
    status,
    sync_write,
    write,
)


def test_instruction_codes():
    assert {i.name: i.value for i in Instruction} == {
        "PING": 0x01,
        "READ": 0x02,
        "WRITE": 0x03,
        "REG_WRITE": 0x04,
        "ACTION": 0x05,
        "RESET": 0x06,
        "SYNC_WRITE": 0x83,
        "BULK_READ": 0x92,
    }
    assert BROADCAST_ID == 0xFE and MAX_PACKET_LEN == 250


def test_error_flags_describe_every_bit_in_words():
    words = [ErrorFlags(1 << bit).describe() for bit in range(7)]
    assert len(set(words)) == 7 and all(w and "," not in w for w in words)
    assert ErrorFlags(0).describe() == "no error"
    both = ErrorFlags.OVERHEATING | ErrorFlags.OVERLOAD
    assert both.describe() == "overheating, overload"
    assert "bit 7" in ErrorFlags(0x81).describe()


def test_servo_error_names_servo_and_flags():
    err = ServoError(7, 0x24)
    assert err.id == 7 and err.flags == ErrorFlags.OVERHEATING | ErrorFlags.OVERLOAD
    text = str(err)
    assert "servo 7" in text and "overheating" in text and "overload" in text
    assert "Torque Limit" in text  # says what to do, too
    again = pickle.loads(pickle.dumps(err))
    assert (again.id, again.flags, str(again)) == (7, err.flags, text)


def test_exception_hierarchy():
    for exc in (DxlTimeout, CorruptPacket, ServoError, PacketArgumentError):
        assert issubclass(exc, ProtocolError)
    assert issubclass(ProtocolError, SnakebotError)
    assert issubclass(PacketArgumentError, ValueError)


def test_packet_error_and_encode():
    packet = Packet(3, 0x20, b"\x01")
    assert packet.error == ErrorFlags.OVERLOAD
    assert decode(packet.encode()) == packet


@pytest.mark.parametrize(
    "build",
    [
        lambda: ping(0xFF),
        lambda: ping(-1),
        lambda: read(1, 256, 1),
        lambda: read(1, 0, 0),
        lambda: write(1, 30, b""),
        lambda: encode_packet(1, 0x100),
        lambda: encode_packet(1, 3, bytes(245)),
        lambda: status(BROADCAST_ID),
        lambda: sync_write(30, 2, {}),
        lambda: sync_write(30, 2, {1: b"\x00"}),
        lambda: sync_write(30, 2, {254: b"\x00\x00"}),
        lambda: bulk_read([]),
        lambda: bulk_read([(1, 30, 2), (1, 36, 2)]),
    ],
)
def test_builders_refuse_impossible_packets(build):
    with pytest.raises(PacketArgumentError):
        build()


def test_longest_packet_fits_and_one_more_byte_does_not():
    assert len(encode_packet(1, 3, bytes(244))) == MAX_PACKET_LEN
    with pytest.raises(PacketArgumentError, match="split"):
        encode_packet(1, 3, bytes(245))


@pytest.mark.parametrize(
    "data",
    [
        b"",
        b"\xff\xff\x01\x02\x01\xfa",
        b"\x00\xff\xff\x01\x02\x01\xfb",
        b"\xff\xff\x01\x02\x01\xfb\x00",
        b"\xff\xff\x01\x02\x01",
    ],
)
def test_decode_rejects_anything_but_one_packet(data):
    with pytest.raises(CorruptPacket):
        decode(data)
