"""The status-packet error bits and the exceptions of the Protocol 1.0 layer.

Every message names the problem in words and says what to try, so the CLI can print it
as it stands (``snakebot.cli.errors``).
"""

from __future__ import annotations

from enum import IntFlag

from snakebot.errors import InputError, RuntimeFailure, SnakebotError


class ErrorFlags(IntFlag):
    """The error byte of a status packet (bit 7 is always 0 on an AX-12)."""

    INPUT_VOLTAGE = 0x01
    ANGLE_LIMIT = 0x02
    OVERHEATING = 0x04
    RANGE = 0x08
    CHECKSUM = 0x10
    OVERLOAD = 0x20
    INSTRUCTION = 0x40

    def describe(self) -> str:
        """The set bits in words, lowest bit first, e.g. "overheating, overload"; "no error"."""
        value = int(self)
        if value == 0:
            return "no error"
        words = [_WORDS[flag] for flag in _ORDER if value & flag]
        if value & 0x80:
            words.append("undefined bit 7")
        return ", ".join(words)


_ORDER = (
    ErrorFlags.INPUT_VOLTAGE,
    ErrorFlags.ANGLE_LIMIT,
    ErrorFlags.OVERHEATING,
    ErrorFlags.RANGE,
    ErrorFlags.CHECKSUM,
    ErrorFlags.OVERLOAD,
    ErrorFlags.INSTRUCTION,
)

_WORDS = {
    ErrorFlags.INPUT_VOLTAGE: "input voltage out of range",
    ErrorFlags.ANGLE_LIMIT: "goal position outside the angle limits",
    ErrorFlags.OVERHEATING: "overheating",
    ErrorFlags.RANGE: "value out of range",
    ErrorFlags.CHECKSUM: "instruction checksum wrong",
    ErrorFlags.OVERLOAD: "overload",
    ErrorFlags.INSTRUCTION: "undefined instruction or ACTION without REG_WRITE",
}

# What a user can do about each bit, in the same order as _ORDER.
_HINTS = {
    ErrorFlags.INPUT_VOLTAGE: "check the supply against the voltage limits (addresses 12-13)",
    ErrorFlags.ANGLE_LIMIT: "keep goals between the CW and CCW angle limits (addresses 6-9)",
    ErrorFlags.OVERHEATING: "let the servo cool and reduce its load",
    ErrorFlags.RANGE: "write values inside the control table's range",
    ErrorFlags.CHECKSUM: "check the wiring and the baud rate (noise corrupts packets)",
    ErrorFlags.OVERLOAD: "remove the load, then write Torque Limit (address 34) to drive again",
    ErrorFlags.INSTRUCTION: "send only PING/READ/WRITE/REG_WRITE/ACTION/RESET/SYNC_WRITE",
}


class ProtocolError(SnakebotError):
    """Something went wrong speaking Protocol 1.0 (the area's base: what is raised is
    one of the classes below, bad input or a runtime failure)."""


class PacketArgumentError(ProtocolError, InputError, ValueError):
    """A request that cannot be made as given: a packet that cannot be built from its
    arguments (bad ID, byte out of range, too long), a READ of a servo that never
    answers one, an instruction no servo answers."""


class DxlTimeout(ProtocolError, RuntimeFailure):
    """No (complete) reply arrived in time."""

    echo_missing: bool = False
    """On a bus known to echo: not even the instruction's own echo came back intact, so
    the instruction itself may have been damaged on the wire."""


class CorruptPacket(ProtocolError, RuntimeFailure):
    """A reply had a bad checksum, an impossible length, or the wrong shape."""


class ServoError(ProtocolError, RuntimeFailure):
    """A servo answered with error bits set in its status packet."""

    def __init__(self, servo_id: int, flags: int) -> None:
        self.id = servo_id
        self.flags = ErrorFlags(flags)
        hints = "; ".join(_HINTS[flag] for flag in _ORDER if self.flags & flag)
        message = f"servo {servo_id} reports: {self.flags.describe()}"
        if hints:
            message += f" ({hints})"
        super().__init__(message)

    def __reduce__(self) -> tuple[type, tuple[int, int]]:
        return (type(self), (self.id, int(self.flags)))
