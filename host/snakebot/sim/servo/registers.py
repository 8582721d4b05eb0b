"""A servo's control table as a register file, checked against its device description.

The table (addresses, sizes, access, write ranges, factory defaults) comes from
:mod:`snakebot.facts.devices` through ``snakebot.formats.protocol.ControlTable``; nothing
here repeats an address except through the register names. A write is checked as a whole before any
byte changes: every byte must fall inside a writable register, multi-byte registers must
be written whole (the AX-12 manual: "both bytes need to be written at the same time"),
and every value must be in its register's range. A failed check writes nothing and says
which error bit to set.
"""

from __future__ import annotations

from dataclasses import dataclass

from snakebot.formats.protocol import ControlTable, Entry, ErrorFlags

_RANGE = int(ErrorFlags.RANGE)

LOCKED_WRITABLE = ("Torque Enable", "Torque Limit")
"""With Lock set, only the registers from Torque Enable to Torque Limit can be written
(addresses 24-35 on the AX-12)."""


@dataclass(frozen=True)
class Change:
    """One register a successful write changed: its entry, old and new values."""

    entry: Entry
    old: int
    new: int


class RegisterFile:
    """The bytes of one servo's control table, with checked writes."""

    def __init__(self, table: ControlTable) -> None:
        self.table = table
        self.image = bytearray(table.default_image())
        # address -> entry for the first byte of every register; per-byte owner map
        self._owner: list[Entry | None] = [None] * table.size
        for entry in table.entries:
            for a in range(entry.address, entry.address + entry.size):
                self._owner[a] = entry
        self._by_name = {e.name: e for e in table.entries}
        first = self._by_name[LOCKED_WRITABLE[0]]
        last = self._by_name[LOCKED_WRITABLE[1]]
        self._locked_span = (first.address, last.address + last.size)
        self._layouts: dict[tuple[int, int, bool], tuple[Entry, ...] | None] = {}
        self._ranges = {e.name: e.value_range() for e in table.entries}

    @property
    def size(self) -> int:
        return self.table.size

    def entry(self, name: str) -> Entry:
        """The register called ``name`` (exact spelling from the description)."""
        return self._by_name[name]

    def get(self, name: str) -> int:
        """The value of register ``name``."""
        e = self._by_name[name]
        if e.size == 1:
            return self.image[e.address]
        return self.image[e.address] | self.image[e.address + 1] << 8

    def set(self, name: str, value: int) -> None:
        """Store ``value`` in register ``name`` unchecked (the servo's own updates)."""
        e = self._by_name[name]
        self.image[e.address] = value & 0xFF
        if e.size == 2:
            self.image[e.address + 1] = (value >> 8) & 0xFF

    def value_range(self, entry: Entry) -> tuple[int, int]:
        """The values a write may store in ``entry``: (lowest, highest)."""
        return self._ranges[entry.name]

    def read(self, address: int, length: int) -> bytes | None:
        """``length`` bytes from ``address``, or None if that runs off the table."""
        if length < 1 or address + length > self.table.size:
            return None
        return bytes(self.image[address : address + length])

    def layout(self, address: int, length: int, locked: bool) -> tuple[Entry, ...] | None:
        """The registers a write of ``length`` bytes at ``address`` covers exactly, or
        None if it touches bytes outside the table, reserved or read-only addresses,
        part of a register, or (``locked``) anything but Torque Enable..Torque Limit."""
        key = (address, length, locked)
        cached = self._layouts.get(key, False)
        if cached is not False:
            return cached
        end = address + length
        layout: tuple[Entry, ...] | None = None
        ok = length > 0 and end <= self.table.size
        if ok and locked:
            ok = self._locked_span[0] <= address and end <= self._locked_span[1]
        if ok:
            entries = []
            a = address
            while a < end:
                e = self._owner[a]
                if e is None or not e.writable or e.address != a or a + e.size > end:
                    break
                entries.append(e)
                a += e.size
            else:
                layout = tuple(entries)
        self._layouts[key] = layout
        return layout

    def check_write(
        self, address: int, data: bytes, *, locked: bool
    ) -> tuple[int, list[tuple[Entry, int]]]:
        """Check a write of ``data`` at ``address``: (error bits, [(entry, value)]).

        The bits are RANGE for bytes outside the table, in reserved or read-only addresses,
        a register written in part, a value out of range, or (with ``locked``) a register
        outside Torque Enable..Torque Limit. No bits (0) means the write is legal
        as far as the table goes; the servo adds its own rules (angle limits, wheel mode).
        """
        layout = self.layout(address, len(data), locked)
        if layout is None:
            return _RANGE, []
        values: list[tuple[Entry, int]] = []
        for e in layout:
            i = e.address - address
            value = data[i] if e.size == 1 else data[i] | data[i + 1] << 8
            low, high = self._ranges[e.name]
            if not low <= value <= high:
                return _RANGE, []
            values.append((e, value))
        return 0, values

    def apply(self, values: list[tuple[Entry, int]]) -> list[Change]:
        """Store checked values; return what changed."""
        changes = []
        for e, value in values:
            old = self.get(e.name)
            self.set(e.name, value)
            changes.append(Change(e, old, value))
        return changes

    def eeprom(self) -> bytes:
        """The EEPROM area's bytes (what survives a power cycle)."""
        return bytes(self.image[: self.table.eeprom_end])

    def load_eeprom(self, data: bytes) -> None:
        """Restore the EEPROM area (e.g. from a state file); read-only bytes are kept."""
        if len(data) != self.table.eeprom_end:
            raise ValueError(
                f"EEPROM image has {len(data)} bytes, the {self.table.model} has "
                f"{self.table.eeprom_end}"
            )
        for e in self.table.entries:
            if e.area == "EEPROM" and e.writable:
                self.image[e.address : e.address + e.size] = data[e.address : e.address + e.size]
