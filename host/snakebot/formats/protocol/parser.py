"""A streaming Protocol 1.0 parser that finds packets in any byte stream, however it
arrives in pieces, and reports what it had to drop.

The resynchronisation rule (the C parser in ``firmware/core/dxl_parser.c`` follows the
same rule, packet for packet). With B the unconsumed bytes, repeat:

1. drop bytes until B starts with ``FF FF`` (a lone trailing ``FF`` is kept);
2. while ``B[2] == FF`` drop one byte, so in ``FF FF FF ..`` the last two FFs are the
   header (an ID of 0xFF can therefore never be seen);
3. once ``LEN = B[3]`` is known: if ``LEN < 2`` or ``LEN + 4 > MAX_PACKET_LEN`` report
   ``Rejected("length", B[:4])``, drop ONE byte and start again;
4. once ``LEN + 4`` bytes are buffered, check the checksum: if it is wrong report
   ``Rejected("checksum", B[:LEN + 4])`` and drop ONE byte (a good packet hidden inside
   the bad one is still found), otherwise report the ``Packet`` and drop its bytes.

Each step waits for more bytes when it needs them, so the result never depends on how
the stream was cut into pieces.
"""

from __future__ import annotations

from snakebot.formats.protocol.errors import CorruptPacket
from snakebot.formats.protocol.instructions import MAX_PACKET_LEN, MIN_LEN_FIELD
from snakebot.formats.protocol.packet import Packet, Rejected

Event = Packet | Rejected


class PacketParser:
    """Feed it bytes as they arrive; it returns the packets (and rejections) completed."""

    def __init__(self) -> None:
        self._buf = bytearray()

    @property
    def pending(self) -> int:
        """Bytes held back because they may start a packet that is not complete yet."""
        return len(self._buf)

    def reset(self) -> None:
        """Forget any partial packet (e.g. after a timeout)."""
        self._buf.clear()

    def feed(self, data: bytes) -> list[Event]:
        """Add ``data`` to the stream; return the events it completes, in stream order."""
        buf = self._buf
        buf += data
        n = len(buf)
        pos = 0
        events: list[Event] = []
        while True:
            # (1) find the header
            if n - pos < 2:
                if n - pos == 1 and buf[pos] != 0xFF:
                    pos += 1
                break
            if buf[pos] != 0xFF or buf[pos + 1] != 0xFF:
                found = buf.find(b"\xff\xff", pos)
                if found < 0:
                    pos = n - 1 if buf[n - 1] == 0xFF else n
                    break
                pos = found
            # (2) the last two FFs of a run are the header
            while pos + 2 < n and buf[pos + 2] == 0xFF:
                pos += 1
            if n - pos < 4:
                break
            # (3) a possible length?
            length = buf[pos + 3]
            if length < MIN_LEN_FIELD or length + 4 > MAX_PACKET_LEN:
                events.append(Rejected("length", bytes(buf[pos : pos + 4])))
                pos += 1
                continue
            end = pos + length + 4
            if end > n:
                break
            # (4) the checksum
            if ~sum(buf[pos + 2 : end - 1]) & 0xFF != buf[end - 1]:
                events.append(Rejected("checksum", bytes(buf[pos:end])))
                pos += 1
                continue
            events.append(Packet(buf[pos + 2], buf[pos + 4], bytes(buf[pos + 5 : end - 1])))
            pos = end
        del buf[:pos]
        return events


def decode(data: bytes) -> Packet:
    """Decode exactly one packet from ``data``; raise ``CorruptPacket`` if it is not one."""
    parser = PacketParser()
    events = parser.feed(data)
    if len(events) == 1 and isinstance(events[0], Packet) and parser.pending == 0:
        packet = events[0]
        if packet.encode() == bytes(data):
            return packet
    raise CorruptPacket(
        f"not one well-formed Protocol 1.0 packet: {bytes(data).hex(' ')} "
        "(check the baud rate and that only one device answers)"
    )
