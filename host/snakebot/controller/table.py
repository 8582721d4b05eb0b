"""The controller's control table as data, loaded from ``protocol/controller.json``.

That file is the one source of the addresses: ``firmware/core/ctl_table.h`` is generated
from it (``protocol/gen_controller_header.py``), and host tools look registers up here by
name, so no address is ever typed twice.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from typing import Any

from snakebot.errors import SnakebotError
from snakebot.paths import protocol_dir

TABLE_FILE = "controller.json"


class ControllerTableError(SnakebotError):
    """An unknown register name, a value out of range, or a broken controller.json."""


@dataclass(frozen=True)
class Register:
    """One register of the controller (``address`` absolute) or one field of a servo record
    (``address`` = offset inside the record)."""

    address: int
    size: int  # bytes, little-endian
    name: str
    access: str  # "R", "W" or "RW"
    default: int
    min: int | None = None  # write range; None when not writable
    max: int | None = None
    signed: bool = False
    unit: str = ""
    description: str = ""
    enum: str | None = None  # name of the enum (see Controller.enums) its values belong to

    @property
    def readable(self) -> bool:
        return "R" in self.access

    @property
    def writable(self) -> bool:
        return "W" in self.access

    @property
    def end(self) -> int:
        return self.address + self.size

    def accepts(self, value: int) -> bool:
        """Whether the controller takes ``value`` in a WRITE of this register."""
        if not self.writable:
            return False
        low, high = self.value_range()
        return low <= value <= high

    def value_range(self) -> tuple[int, int]:
        """The write range, or the full range of the field's type when none is given."""
        bits = 8 * self.size
        if self.signed:
            low, high = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
        else:
            low, high = 0, (1 << bits) - 1
        return (low if self.min is None else self.min, high if self.max is None else self.max)

    def encode(self, value: int) -> bytes:
        """The bytes a WRITE of ``value`` carries; ControllerTableError if out of range."""
        if not self.accepts(value):
            low, high = self.value_range()
            what = "is not writable" if not self.writable else f"takes {low}..{high}"
            raise ControllerTableError(
                f"cannot write {value} to controller register {self.name!r}: it {what}"
            )
        return int(value).to_bytes(self.size, "little", signed=self.signed)

    def decode(self, data: bytes) -> int:
        """The value held in ``data`` (exactly ``size`` bytes)."""
        if len(data) != self.size:
            raise ControllerTableError(
                f"{self.name!r} is {self.size} bytes, got {len(data)}: read it whole"
            )
        return int.from_bytes(data, "little", signed=self.signed)


@dataclass(frozen=True)
class Controller:
    """The controller's control table: registers, the servo window, limits and enums."""

    model_number: int
    firmware_version: int
    default_id: int
    table_size: int
    limits: dict[str, int]
    registers: tuple[Register, ...]
    servo_window_address: int
    servo_record_size: int
    servo_records: int  # records shown at once (one page)
    servo_fields: tuple[Register, ...]
    enums: dict[str, dict[str, int]]

    def register(self, name: str) -> Register:
        """The register called ``name`` (case-insensitive), e.g. "Speed Scale"."""
        key = name.strip().lower()
        for reg in self.registers:
            if reg.name.lower() == key:
                return reg
        known = ", ".join(r.name for r in self.registers)
        raise ControllerTableError(f"no controller register {name!r}: known are {known}")

    def servo_field(self, name: str) -> Register:
        """The servo-record field called ``name`` (its address is the offset in a record)."""
        key = name.strip().lower()
        for field in self.servo_fields:
            if field.name.lower() == key:
                return field
        known = ", ".join(f.name for f in self.servo_fields)
        raise ControllerTableError(f"no servo-window field {name!r}: known are {known}")

    def servo_page(self, joint: int) -> tuple[int, int]:
        """(page, slot): write ``page`` to Servo Page, then the joint is record ``slot``."""
        if not 0 <= joint < self.limits["max_joints"]:
            raise ControllerTableError(
                f"joint index {joint} is outside the roster: the controller has joints "
                f"0..{self.limits['max_joints'] - 1}"
            )
        return divmod(joint, self.servo_records)

    def servo_address(self, slot: int, name: str) -> int:
        """Absolute address of field ``name`` of record ``slot`` in the servo window."""
        if not 0 <= slot < self.servo_records:
            raise ControllerTableError(
                f"servo window slot {slot} does not exist: slots are 0..{self.servo_records - 1}"
            )
        return (
            self.servo_window_address
            + slot * self.servo_record_size
            + self.servo_field(name).address
        )

    def decode(self, start: int, data: bytes) -> dict[str, int]:
        """Values of every register lying wholly inside ``data`` read from ``start``."""
        values = {}
        for reg in self.registers:
            if reg.readable and start <= reg.address and reg.end <= start + len(data):
                values[reg.name] = reg.decode(data[reg.address - start : reg.end - start])
        return values

    def decode_servo_window(self, data: bytes) -> list[dict[str, int]]:
        """One dict per whole servo record in ``data`` read from the window's first byte."""
        records = []
        for slot in range(min(self.servo_records, len(data) // self.servo_record_size)):
            base = slot * self.servo_record_size
            records.append(
                {f.name: f.decode(data[base + f.address : base + f.end]) for f in self.servo_fields}
            )
        return records


def _register(entry: dict[str, Any], address_key: str) -> Register:
    return Register(
        address=entry[address_key],
        size=entry["size"],
        name=entry["name"],
        access=entry["access"],
        default=entry.get("default", 0),
        min=entry.get("min"),
        max=entry.get("max"),
        signed=entry.get("signed", False),
        unit=entry.get("unit", ""),
        description=entry.get("description", ""),
        enum=entry.get("enum"),
    )


@cache
def load() -> Controller:
    """The controller table (read once from protocol/controller.json)."""
    path = protocol_dir() / TABLE_FILE
    try:
        raw = json.loads(path.read_text())
        window = raw["servo_window"]
        return Controller(
            model_number=raw["model_number"],
            firmware_version=raw["firmware_version"],
            default_id=raw["default_id"],
            table_size=raw["table_size"],
            limits=dict(raw["limits"]),
            registers=tuple(_register(e, "address") for e in raw["registers"]),
            servo_window_address=window["address"],
            servo_record_size=window["record_size"],
            servo_records=window["records"],
            servo_fields=tuple(_register(f, "offset") for f in window["fields"]),
            enums={name: dict(e["values"]) for name, e in raw["enums"].items()},
        )
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ControllerTableError(
            f"cannot read the controller table {path}: {exc}; restore it from git"
        ) from exc
