"""Protocol 1.0 instructions: the instruction table, one checksum, one framing function,
and a builder per instruction. Every builder returns the exact bytes to put on the wire.

Packet: ``FF FF ID LEN INST P1..PN CHK`` with ``LEN = N + 2`` and
``CHK = ~(ID + LEN + INST + P1 + ... + PN) & 0xFF``. A status packet has the same frame
with the error byte in place of the instruction.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from enum import IntEnum

from snakebot.formats.protocol.errors import PacketArgumentError

HEADER = b"\xff\xff"
BITS_PER_BYTE = 10  # 8N1 on every link (servo bus, PC link): start, 8 data bits, stop
BROADCAST_ID = 0xFE
MAX_ID = 0xFD  # highest addressable device ID (253)
MAX_PACKET_LEN = 250  # whole packet, header to checksum: ROBOTIS's SDK cap
FRAME_RESET_S = 0.1  # a pause this long inside a packet makes an AX-12 drop the packet
MIN_LEN_FIELD = 2  # LEN counts the instruction/error byte and the checksum
MAX_LEN_FIELD = MAX_PACKET_LEN - 4  # 246
MAX_PARAMS = MAX_LEN_FIELD - 2  # 244


class Instruction(IntEnum):
    """Protocol 1.0 instruction codes."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    RESET = 0x06
    SYNC_WRITE = 0x83
    BULK_READ = 0x92


def checksum(body: bytes) -> int:
    """The checksum of ``body`` = ID, LEN, INST/ERR, params: the low byte of the inverted sum."""
    return ~sum(body) & 0xFF


def _byte(name: str, value: int, low: int = 0, high: int = 0xFF) -> int:
    if not isinstance(value, int) or not low <= value <= high:
        raise PacketArgumentError(f"{name} must be an integer {low}..{high}, got {value!r}")
    return value


def _packet_id(value: int) -> int:
    # 0xFF can never be an ID: FF FF FF would read as a longer header (see the parser).
    return _byte("servo ID", value, 0, BROADCAST_ID)


def _device_id(value: int) -> int:
    return _byte("servo ID", value, 0, MAX_ID)


def encode_packet(id: int, code: int, params: bytes = b"") -> bytes:
    """Frame one packet: header, ID, LEN, instruction or error byte, params, checksum."""
    params = bytes(params)
    _packet_id(id)
    _byte("instruction/error code", code)
    if len(params) > MAX_PARAMS:
        raise PacketArgumentError(
            f"{len(params)} parameter bytes do not fit one packet (at most {MAX_PARAMS}, "
            f"{MAX_PACKET_LEN} bytes in all): split the transfer into several packets"
        )
    return frame(id, code, params)


def frame(id: int, code: int, params: bytes = b"") -> bytes:
    """:func:`encode_packet` without the checks, for callers whose values are valid by
    construction (an emulated servo answering thousands of READs a second)."""
    body = bytes((id, len(params) + 2, code)) + params
    return HEADER + body + bytes((checksum(body),))


def ping(id: int) -> bytes:
    """PING: ask a device to answer with an empty status packet."""
    return encode_packet(id, Instruction.PING)


def read(id: int, address: int, length: int) -> bytes:
    """READ ``length`` bytes of the control table starting at ``address``."""
    params = bytes((_byte("address", address), _byte("read length", length, 1, MAX_PARAMS)))
    return encode_packet(id, Instruction.READ, params)


def _address_and_data(address: int, data: bytes) -> bytes:
    data = bytes(data)
    if not data:
        raise PacketArgumentError("nothing to write: give at least one data byte")
    return bytes((_byte("address", address),)) + data


def write(id: int, address: int, data: bytes) -> bytes:
    """WRITE ``data`` into the control table at ``address`` (takes effect at once)."""
    return encode_packet(id, Instruction.WRITE, _address_and_data(address, data))


def reg_write(id: int, address: int, data: bytes) -> bytes:
    """REG_WRITE: like WRITE, but held until an ACTION arrives."""
    return encode_packet(id, Instruction.REG_WRITE, _address_and_data(address, data))


def action(id: int = BROADCAST_ID) -> bytes:
    """ACTION: apply the writes registered with REG_WRITE (usually broadcast)."""
    return encode_packet(id, Instruction.ACTION)


def reset(id: int) -> bytes:
    """RESET: restore the device's factory defaults (its ID becomes 1)."""
    return encode_packet(id, Instruction.RESET)


def sync_write(address: int, length: int, data: Mapping[int, bytes]) -> bytes:
    """SYNC_WRITE (broadcast): ``length`` bytes at ``address`` to several devices at once.

    ``data`` maps each device ID to exactly ``length`` bytes; devices are sent in the
    mapping's order. Params: address, length, then ID and its bytes per device.
    """
    _byte("address", address)
    _byte("data length", length, 1, MAX_PARAMS - 3)
    if not data:
        raise PacketArgumentError("SYNC_WRITE needs at least one device")
    params = bytearray((address, length))
    for device, chunk in data.items():
        chunk = bytes(chunk)
        if len(chunk) != length:
            raise PacketArgumentError(
                f"SYNC_WRITE data for servo {device} is {len(chunk)} bytes, expected {length}"
            )
        params.append(_device_id(device))
        params += chunk
    return encode_packet(BROADCAST_ID, Instruction.SYNC_WRITE, bytes(params))


def bulk_read(requests: Iterable[tuple[int, int, int]]) -> bytes:
    """BULK_READ (broadcast; MX series, an AX-12 ignores it): ``(id, address, length)`` each.

    Params: 0x00, then length, ID, address per device (in that order on the wire).
    """
    params = bytearray((0x00,))
    seen: set[int] = set()
    for device, address, length in requests:
        if _device_id(device) in seen:
            raise PacketArgumentError(f"servo {device} appears twice in one BULK_READ")
        seen.add(device)
        params += bytes(
            (_byte("read length", length, 1, MAX_PARAMS), device, _byte("address", address))
        )
    if len(params) == 1:
        raise PacketArgumentError("BULK_READ needs at least one (id, address, length)")
    return encode_packet(BROADCAST_ID, Instruction.BULK_READ, bytes(params))


def status(id: int, error: int = 0, params: bytes = b"") -> bytes:
    """A device's status packet: its ID, error byte and returned data."""
    return encode_packet(_device_id(id), error, params)
