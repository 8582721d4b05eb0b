"""Servo control tables, as the servo tools and the emulator look at them: a thin view
of the device descriptions in :mod:`snakebot.facts.devices` (the one source of the addresses;
``firmware/core/ax12_table.h`` is generated from the same files)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache

from snakebot.errors import quoted
from snakebot.facts import devices
from snakebot.facts.devices import Device, DeviceError, Register
from snakebot.formats.protocol.errors import ProtocolError

Entry = Register
"""One register of a servo's control table (the name the servo tools use)."""


class ControlTableError(ProtocolError, DeviceError):
    """An unknown model or register name, or a broken device description."""


@dataclass(frozen=True)
class ControlTable:
    """The control table of one servo model."""

    device: Device

    @property
    def model(self) -> str:
        return self.device.name

    @property
    def model_number(self) -> int:
        return self.device.model_number

    @property
    def entries(self) -> tuple[Entry, ...]:
        return self.device.registers

    @property
    def size(self) -> int:
        """Bytes from address 0 to the end of the table."""
        return self.device.table_size

    @property
    def eeprom_end(self) -> int:
        """The first RAM address."""
        assert self.device.eeprom_end is not None  # every servo has an EEPROM area
        return self.device.eeprom_end

    @classmethod
    def for_model(cls, model: str) -> ControlTable:
        """The table of servo ``model`` ("AX-12A", "AX-12W", ...; case-insensitive)."""
        for name in devices.names("servo"):
            if name.lower() == model.strip().lower():
                return _table(name)
        raise ControlTableError(
            f"unknown servo model {quoted(model)}: known models are {', '.join(cls.models())}"
        )

    @classmethod
    def for_model_number(cls, number: int) -> ControlTable:
        """The table whose Model Number (address 0) is ``number`` (12, 300, ...)."""
        try:
            return _table(devices.by_model_number(number).name)
        except DeviceError as exc:
            raise ControlTableError(str(exc)) from None

    @staticmethod
    def models() -> tuple[str, ...]:
        """The servo models described."""
        return devices.names("servo")

    def by_name(self, name: str) -> Entry:
        """The register called ``name`` (e.g. "Goal Position"; case-insensitive)."""
        try:
            return self.device.register(name)
        except DeviceError as exc:
            raise ControlTableError(str(exc)) from None

    def by_address(self, address: int) -> Entry | None:
        """The register starting at ``address``, or None (reserved or mid-register)."""
        return self.device.at(address)

    def __iter__(self) -> Iterator[Entry]:
        return iter(self.device.registers)

    def default_image(self) -> bytes:
        """The table's bytes after a factory reset (see :meth:`Device.default_image`)."""
        return self.device.default_image()


@cache
def _table(name: str) -> ControlTable:
    return ControlTable(devices.load(name))
