"""Status Return Level: which instructions each servo answers, as the client assumes it
(told, or learnt from the client's own writes to the register), so a transaction waits
for a reply only when one will come."""

from __future__ import annotations

from snakebot.formats.protocol import BROADCAST_ID, Instruction
from snakebot.link.transport.client_state import ClientState

DEFAULT_STATUS_RETURN_LEVEL = 2
"""Factory setting: every instruction addressed to one servo is answered."""

NEEDS_LEVEL = {
    Instruction.PING: 0,
    Instruction.READ: 1,
    Instruction.WRITE: 2,
    Instruction.REG_WRITE: 2,
    Instruction.ACTION: 2,
    Instruction.RESET: 2,
}
"""The lowest Status Return Level at which a servo answers each instruction (any other: 3,
never)."""


def check_level(level: int) -> int:
    """``level`` if it is a Status Return Level (0, 1 or 2), else ValueError."""
    if level not in (0, 1, 2):
        raise ValueError(f"Status Return Level must be 0, 1 or 2, got {level!r}")
    return level


class StatusLevels(ClientState):
    """The client's Status Return Level bookkeeping (a part of
    :class:`~snakebot.link.transport.client.DxlClient`)."""

    def status_return_level(self, servo_id: int) -> int:
        """The Status Return Level this client assumes for ``servo_id``."""
        return self._levels.get(servo_id, self._default_level)

    def set_status_return_level(self, servo_id: int, level: int) -> None:
        """Tell the client what ``servo_id`` is set to (broadcast ID: every servo). This
        does not write the servo; write its Status Return Level register for that."""
        level = check_level(level)
        if servo_id == BROADCAST_ID:
            self._default_level = level
            self._levels.clear()
        else:
            self._levels[servo_id] = level

    def _answers(self, servo_id: int, code: int) -> bool:
        if servo_id == BROADCAST_ID:
            return False
        return self.status_return_level(servo_id) >= NEEDS_LEVEL.get(code, 3)

    def _level_written(self, address: int, data: bytes) -> int | None:
        """The Status Return Level a WRITE of ``data`` at ``address`` sets, if it sets one."""
        where = self._level_address
        if where is None or not address <= where < address + len(data):
            return None
        return data[where - address]

    def _after_write(self, servo_id: int, address: int, data: bytes) -> None:
        level = self._level_written(address, data)
        if level is not None and level <= 2:
            self.set_status_return_level(servo_id, level)
