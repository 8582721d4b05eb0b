"""What the stream parser yields: a checked packet, or the bytes it had to drop."""

from __future__ import annotations

from dataclasses import dataclass

from snakebot.formats.protocol.errors import ErrorFlags
from snakebot.formats.protocol.instructions import encode_packet


@dataclass(frozen=True)
class Packet:
    """One checked packet. ``code`` is the instruction (instruction packet) or the error
    byte (status packet): the frame does not say which, the direction does."""

    id: int
    code: int
    params: bytes = b""

    def encode(self) -> bytes:
        """The packet's bytes on the wire, header to checksum."""
        return encode_packet(self.id, self.code, self.params)

    @property
    def error(self) -> ErrorFlags:
        """The error bits, reading ``code`` as a status packet's error byte."""
        return ErrorFlags(self.code)


@dataclass(frozen=True)
class Rejected:
    """Bytes the parser dropped: ``reason`` is "checksum" (``data`` = the whole candidate
    packet) or "length" (``data`` = header, ID and the impossible LEN byte)."""

    reason: str
    data: bytes
