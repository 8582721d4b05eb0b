"""What every register-level peripheral model shares: a base address, a size, a name, and
reads and writes by offset at a known time. An access to an offset a model does not know
is :class:`~snakebot.sim.mcu.errors.UnmodelledAccess` in strict mode (tests, the default)
and otherwise reads as zero and ignores the write, counted in :attr:`Peripheral.unmodelled`.
"""

from __future__ import annotations

from collections.abc import Callable

from snakebot.sim.mcu.errors import UnmodelledAccess

Clock = Callable[[], float]
"""Returns the machine's time now (seconds)."""


def kept_in(struct: str, field: str) -> property:
    """An attribute that lives in ``field`` of the cffi struct the model holds as
    ``struct``, where the C side reads and writes it too."""

    def get(self: object) -> int | float:
        return getattr(getattr(self, struct), field)

    def put(self: object, value: float) -> None:
        setattr(getattr(self, struct), field, value)

    return property(get, put)


class Peripheral:
    """A block of registers at ``base`` (``size`` bytes)."""

    name = "peripheral"
    size = 1024  # the block an STM32F1 peripheral occupies

    def __init__(self, base: int, *, strict: bool = True) -> None:
        self.base = base
        self.strict = strict
        self.unmodelled: list[str] = []

    def read(self, offset: int, size: int) -> int:
        """The value a ``size``-byte read at ``offset`` returns."""
        return self.unknown(offset, size, None)

    def write(self, offset: int, size: int, value: int) -> None:
        """A ``size``-byte write of ``value`` at ``offset``."""
        self.unknown(offset, size, value)

    def reset(self) -> None:
        """Back to the reset values (RM0008's tables)."""

    def unknown(self, offset: int, size: int, value: int | None) -> int:
        """An access the model does not cover: an error in strict mode, else zero."""
        what = "read" if value is None else f"write of 0x{value:X}"
        message = (
            f"{self.name}: {size}-byte {what} at 0x{self.base + offset:08X} (offset "
            f"0x{offset:03X}) is not modelled"
        )
        if self.strict:
            raise UnmodelledAccess(message + ": model the register in snakebot.sim.mcu")
        self.unmodelled.append(message)
        return 0

    def word_only(self, offset: int, size: int, value: int | None) -> bool:
        """Whether the access is a whole aligned word (what the firmware always does on
        these registers); any other width is :meth:`unknown`."""
        if size == 4 and offset % 4 == 0:
            return True
        self.unknown(offset, size, value)
        return False
