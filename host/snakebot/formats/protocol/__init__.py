"""Dynamixel Protocol 1.0, as the AX-12 servos and the CM-530 controller speak it.

Build packets with the instruction builders, find them in a byte stream with
``PacketParser``, and look registers up in ``ControlTable``. See protocol/README.md.
Sending them over a port is :mod:`snakebot.link.transport`.

May import: as the ``formats`` layer (``facts`` and the package root).
"""

from snakebot.formats.protocol.control_table import ControlTable, ControlTableError, Entry
from snakebot.formats.protocol.errors import (
    CorruptPacket,
    DxlTimeout,
    ErrorFlags,
    PacketArgumentError,
    ProtocolError,
    ServoError,
)
from snakebot.formats.protocol.instructions import (
    BROADCAST_ID,
    FRAME_RESET_S,
    MAX_ID,
    MAX_PACKET_LEN,
    MAX_PARAMS,
    Instruction,
    action,
    bulk_read,
    checksum,
    encode_packet,
    ping,
    read,
    reg_write,
    reset,
    status,
    sync_write,
    write,
)
from snakebot.formats.protocol.packet import Packet, Rejected
from snakebot.formats.protocol.parser import PacketParser, decode

__all__ = [
    "BROADCAST_ID",
    "MAX_ID",
    "FRAME_RESET_S",
    "MAX_PACKET_LEN",
    "MAX_PARAMS",
    "ControlTable",
    "ControlTableError",
    "CorruptPacket",
    "DxlTimeout",
    "Entry",
    "ErrorFlags",
    "Instruction",
    "Packet",
    "PacketArgumentError",
    "PacketParser",
    "ProtocolError",
    "Rejected",
    "ServoError",
    "action",
    "bulk_read",
    "checksum",
    "decode",
    "encode_packet",
    "ping",
    "read",
    "reg_write",
    "reset",
    "status",
    "sync_write",
    "write",
]
