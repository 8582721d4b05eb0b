"""Writes: WRITE (waiting for its status when the servo answers, sent again after a RANGE
error that only damage explains), REG_WRITE and ACTION, RESET, and SYNC_WRITE to
several servos at once; each keeps the client's Status Return Levels up to date."""

from __future__ import annotations

from collections.abc import Mapping

from snakebot.formats import protocol
from snakebot.formats.protocol import BROADCAST_ID, ErrorFlags, Instruction, ServoError
from snakebot.link.transport.client_state import ClientState
from snakebot.link.transport.levels import DEFAULT_STATUS_RETURN_LEVEL
from snakebot.link.transport.transaction import require_device


def encode_uint(value: int, size: int) -> bytes:
    if not isinstance(value, int) or not 0 <= value < 1 << (8 * size):
        raise ValueError(f"value must be an integer 0..{(1 << (8 * size)) - 1}, got {value!r}")
    return value.to_bytes(size, "little")


class Writes(ClientState):
    """Instructions that change servos (a part of
    :class:`~snakebot.link.transport.client.DxlClient`)."""

    def write(self, servo_id: int, address: int, data: bytes) -> None:
        """WRITE ``data`` at ``address`` (waits for the status if the servo sends one)."""
        data = bytes(data)
        packet = protocol.write(servo_id, address, data)
        wait = self._answers(servo_id, Instruction.WRITE)
        level = self._level_written(address, data)
        if level is not None:
            # Whether this very write is answered depends on the level before and after.
            wait = wait and level >= 2
        if wait:
            self._transact_write(packet, servo_id, address, data)
        else:
            self.send(packet)
        self._after_write(servo_id, address, data)

    def _transact_write(self, packet: bytes, servo_id: int, address: int, data: bytes) -> None:
        """A WRITE that waits for its status. A RANGE error for data that the register
        description says is in range means the servo heard other data (damage the
        checksum let through), so the WRITE is sent again, like after a damaged reply."""
        in_range = bool(self._ranges_within(address, len(data))) and (
            self._out_of_range(address, data) is None
        )
        for attempt in range(1 + self.retries):
            try:
                self.transact(packet, servo_id, 0)
                return
            except ServoError as exc:
                damaged = in_range and exc.flags & ErrorFlags.RANGE
                if not damaged or attempt == self.retries:
                    raise

    def write_u8(self, servo_id: int, address: int, value: int) -> None:
        """WRITE one byte."""
        self.write(servo_id, address, encode_uint(value, 1))

    def write_u16(self, servo_id: int, address: int, value: int) -> None:
        """WRITE a 2-byte little-endian word (e.g. Goal Position at 30)."""
        self.write(servo_id, address, encode_uint(value, 2))

    def reg_write(self, servo_id: int, address: int, data: bytes) -> None:
        """REG_WRITE: stage ``data`` at ``address`` until :meth:`action`."""
        self._exchange(protocol.reg_write(servo_id, address, bytes(data)), servo_id, 0)

    def action(self, servo_id: int = BROADCAST_ID) -> None:
        """ACTION: apply staged REG_WRITEs (broadcast by default, so no reply)."""
        self._exchange(protocol.action(servo_id), servo_id, 0)

    def reset(self, servo_id: int) -> None:
        """RESET ``servo_id`` to factory defaults (ID 1, 1 Mbps, Status Return Level 2)."""
        require_device(servo_id, "RESET")
        self._exchange(protocol.reset(servo_id), servo_id, 0)
        self._levels.pop(servo_id, None)
        self._levels[1] = DEFAULT_STATUS_RETURN_LEVEL

    def sync_write(self, address: int, length: int, data: Mapping[int, bytes]) -> None:
        """SYNC_WRITE ``length`` bytes at ``address`` to each servo in ``data`` (no reply)."""
        self.send(protocol.sync_write(address, length, data))
        for servo_id, chunk in data.items():
            self._after_write(servo_id, address, bytes(chunk))
