"""Servo control tables as data, loaded from ``protocol/ax12.json`` (the one source of the
addresses; ``firmware/core/ax12_table.h`` is generated from the same file)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, replace
from functools import cache
from typing import Any

from snakebot.paths import protocol_dir
from snakebot.protocol.errors import ProtocolError

TABLE_FILE = "ax12.json"


class ControlTableError(ProtocolError):
    """An unknown model or register name, or a broken control-table file."""


@dataclass(frozen=True)
class Entry:
    """One register of a control table."""

    address: int
    size: int  # bytes, little-endian
    name: str
    access: str  # "R" or "RW"
    default: int | None  # factory value; None when there is none
    min: int | None  # write range; None when read-only or undocumented
    max: int | None
    area: str  # "EEPROM" (kept across power cycles) or "RAM"
    unit: str = ""
    note: str = ""
    emulator_default: int | None = None  # used by emulated servos where the factory varies

    @property
    def writable(self) -> bool:
        return self.access == "RW"

    def accepts(self, value: int) -> bool:
        """Whether writing ``value`` is within this register's documented range."""
        low = 0 if self.min is None else self.min
        high = (1 << (8 * self.size)) - 1 if self.max is None else self.max
        return self.writable and low <= value <= high


@dataclass(frozen=True)
class ControlTable:
    """The control table of one servo model."""

    model: str
    model_number: int
    entries: tuple[Entry, ...]
    size: int  # bytes from address 0 to the end of the last register
    eeprom_end: int  # first RAM address

    @classmethod
    def for_model(cls, model: str) -> ControlTable:
        """The table of ``model`` ("AX-12A", "AX-12W"; case-insensitive)."""
        tables = _load()
        for name, table in tables.items():
            if name.lower() == model.strip().lower():
                return table
        raise ControlTableError(
            f"unknown servo model {model!r}: known models are {', '.join(tables)}"
        )

    @classmethod
    def for_model_number(cls, number: int) -> ControlTable:
        """The table whose Model Number (address 0) is ``number`` (12, 300)."""
        for table in _load().values():
            if table.model_number == number:
                return table
        known = ", ".join(f"{t.model_number} ({t.model})" for t in _load().values())
        raise ControlTableError(f"unknown model number {number}: known are {known}")

    @staticmethod
    def models() -> tuple[str, ...]:
        """The model names described in ax12.json."""
        return tuple(_load())

    def by_name(self, name: str) -> Entry:
        """The register called ``name`` (e.g. "Goal Position"; case-insensitive)."""
        wanted = name.strip().lower()
        for entry in self.entries:
            if entry.name.lower() == wanted:
                return entry
        raise ControlTableError(
            f"{self.model} has no register {name!r}: known registers are "
            + ", ".join(e.name for e in self.entries)
        )

    def by_address(self, address: int) -> Entry | None:
        """The register starting at ``address``, or None (reserved or mid-register)."""
        for entry in self.entries:
            if entry.address == address:
                return entry
        return None

    def __iter__(self) -> Iterator[Entry]:
        return iter(self.entries)

    def default_image(self) -> bytes:
        """The table's bytes after a factory reset: defaults (or emulator defaults) in
        place, little-endian; reserved and default-less registers are 0."""
        image = bytearray(self.size)
        for entry in self.entries:
            value = entry.default if entry.default is not None else entry.emulator_default
            if value is not None:
                image[entry.address : entry.address + entry.size] = value.to_bytes(
                    entry.size, "little"
                )
        return bytes(image)


_ENTRY_FIELDS = set(Entry.__dataclass_fields__)


def _entry(raw: dict[str, Any]) -> Entry:
    unknown = set(raw) - _ENTRY_FIELDS
    if unknown:
        raise ControlTableError(f"{TABLE_FILE}: unknown field(s) {sorted(unknown)} in {raw}")
    return Entry(**raw)


def _check(model: str, entries: tuple[Entry, ...], eeprom_end: int, size: int) -> None:
    end = 0
    for entry in sorted(entries, key=lambda e: e.address):
        problem = None
        if entry.address < end:
            problem = "overlaps the register before it"
        elif entry.size not in (1, 2) or entry.address + entry.size > size:
            problem = "has an impossible size"
        elif entry.access not in ("R", "RW"):
            problem = "has access other than R/RW"
        elif entry.area != ("EEPROM" if entry.address < eeprom_end else "RAM"):
            problem = "is in the wrong area"
        if problem:
            raise ControlTableError(
                f"{TABLE_FILE}: {model} register {entry.name!r} {problem}: fix the file"
            )
        end = entry.address + entry.size


@cache
def _load() -> dict[str, ControlTable]:
    path = protocol_dir() / TABLE_FILE
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ControlTableError(f"cannot read {path}: {exc}") from exc
    eeprom_end, size = doc["eeprom_end"], doc["table_size"]
    tables: dict[str, ControlTable] = {}
    for model, spec in doc["models"].items():
        if "based_on" in spec:
            base = tables[spec["based_on"]]
            overrides = {name.lower(): value for name, value in spec.get("defaults", {}).items()}
            entries = tuple(
                replace(e, default=overrides.pop(e.name.lower(), e.default)) for e in base.entries
            )
            if overrides:
                raise ControlTableError(f"{TABLE_FILE}: {model} overrides unknown {overrides}")
        else:
            entries = tuple(_entry(raw) for raw in spec["entries"])
        _check(model, entries, eeprom_end, size)
        tables[model] = ControlTable(model, spec["model_number"], entries, size, eeprom_end)
    return tables
