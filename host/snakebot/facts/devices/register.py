"""One register of a device's control table."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from snakebot.facts.devices.errors import DeviceError
from snakebot.facts.devices.units import Encoding, Scale


@dataclass(frozen=True)
class Register:
    """A register: where it is, how wide, who may write what, and what its steps mean.

    For a field of the controller's servo window ``address`` is the offset in a record.
    A register's *raw* value is the integer its bytes hold (signed for two's complement,
    unsigned otherwise: that is what ``min``/``max`` bound); its *value* applies the
    encoding (a sign-magnitude speed becomes negative for CW); its *units* apply the scale.
    """

    address: int
    size: int  # bytes, little-endian
    name: str
    access: str  # "R", "W" (reads as 0) or "RW"
    default: int | None = None  # factory value; None when there is none
    min: int | None = None  # write range; None when not writable or not documented
    max: int | None = None
    area: str | None = None  # "EEPROM" (kept across power cycles), "RAM", None (no areas)
    scale: Scale | None = None
    encoding: Encoding = Encoding.UNSIGNED
    description: str = ""
    emulator_default: int | None = None  # what emulated servos use where the factory varies
    enum: str | None = None  # name of the value set (Device.enums) its values belong to
    read_min: int | None = None  # range a value read lies in, where it is narrower than
    read_max: int | None = None  # the field (a read-only register's physical range)

    @property
    def readable(self) -> bool:
        return "R" in self.access

    @property
    def writable(self) -> bool:
        return "W" in self.access

    @property
    def end(self) -> int:
        return self.address + self.size

    @property
    def signed(self) -> bool:
        """Whether the raw value is two's complement."""
        return self.encoding is Encoding.TWOS_COMPLEMENT

    @property
    def unit(self) -> str:
        """The scale in words ("300/1023 deg"), or "" when the register has none."""
        return "" if self.scale is None else str(self.scale)

    @property
    def note(self) -> str:
        """The description (the name the servo tools used)."""
        return self.description

    def value_range(self) -> tuple[int, int]:
        """The write range, or the full range of the field's type when none is given."""
        return self._write_range

    @cached_property
    def _write_range(self) -> tuple[int, int]:
        # worked out once: every encode (a control loop's goals, each tick) checks it
        bits = 8 * min(self.size, 4)
        if self.signed:
            low, high = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
        else:
            low, high = 0, (1 << bits) - 1
        return (low if self.min is None else self.min, high if self.max is None else self.max)

    def read_range(self) -> tuple[int, int] | None:
        """The range every raw value read from this register lies in, where one is known:
        its read range, else its write range, else what its sign-magnitude encoding can
        hold; None when any value of the field is possible."""
        if self.read_min is not None and self.read_max is not None:
            return self.read_min, self.read_max
        if self.min is not None and self.max is not None:
            return self.min, self.max
        mask = self.encoding.magnitude_mask
        if mask is not None:  # the magnitude and the direction bit above it
            return 0, (mask << 1) | 1
        return None

    def accepts(self, value: int) -> bool:
        """Whether ``value`` (raw) is a legal WRITE of this register."""
        if not self.writable:
            return False
        low, high = self.value_range()
        return low <= value <= high

    def encode(self, value: int) -> bytes:
        """The bytes a WRITE of raw ``value`` carries; DeviceError if it is not legal."""
        if not self.accepts(value):
            low, high = self.value_range()
            what = "is not writable" if not self.writable else f"takes {low}..{high}"
            raise DeviceError(f"cannot write {value} to register {self.name!r}: it {what}")
        return int(value).to_bytes(self.size, "little", signed=self.signed)

    def decode(self, data: bytes) -> int:
        """The raw value held in ``data`` (exactly ``size`` bytes, little-endian)."""
        if len(data) != self.size:
            raise DeviceError(f"{self.name!r} is {self.size} bytes, got {len(data)}: read it whole")
        return int.from_bytes(data, "little", signed=self.signed)

    def value(self, raw: int) -> int:
        """The signed value of ``raw`` under this register's encoding."""
        return self.encoding.decode_value(raw)

    def raw(self, value: int) -> int:
        """The raw value for the signed ``value`` (inverse of :meth:`value`)."""
        return self.encoding.encode_value(value)

    def _scale(self) -> Scale:
        if self.scale is None:
            raise DeviceError(f"register {self.name!r} has no unit: use its raw value")
        return self.scale

    def to_units(self, raw: int, unit: str | None = None) -> float:
        """``raw`` in physical units: the scale's own, or ``unit`` ("rad", "rad/s", ...)."""
        scale = self._scale()
        step = float(scale.factor) if unit is None else scale.factor_in(unit)
        return self.value(raw) * step

    def from_units(self, amount: float, unit: str | None = None) -> int:
        """The raw value nearest ``amount`` physical units (not range-checked: see
        :meth:`accepts`)."""
        scale = self._scale()
        step = float(scale.factor) if unit is None else scale.factor_in(unit)
        return self.raw(round(amount / step))
