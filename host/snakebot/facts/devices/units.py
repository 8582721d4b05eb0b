"""Scales (a register's unit and the size of one step) and value encodings.

A scale's factor is kept as an exact fraction, so ``[300, 1023]`` degrees per tick stays
exact until a consumer asks for a float, and the C generator can round fixed-point
constants once, from the exact value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from fractions import Fraction

from snakebot.errors import quoted
from snakebot.facts.devices.errors import DeviceError

# How many of the second unit make one of the first: definitions of the units, not device
# facts, so they live here and nowhere else.
_CONVERSIONS: dict[tuple[str, str], float] = {
    ("deg", "rad"): math.pi / 180.0,
    ("rpm", "deg/s"): 360.0 / 60.0,
    ("rpm", "rad/s"): 2.0 * math.pi / 60.0,
    ("s", "ms"): 1e3,
    ("s", "us"): 1e6,
    ("ms", "us"): 1e3,
    ("rad", "mrad"): 1e3,
    ("rad/s", "mrad/s"): 1e3,
}


def conversion(unit: str, to: str) -> float:
    """How many ``to`` make one ``unit`` ("deg" -> "rad": pi / 180)."""
    if unit == to:
        return 1.0
    if (unit, to) in _CONVERSIONS:
        return _CONVERSIONS[(unit, to)]
    if (to, unit) in _CONVERSIONS:
        return 1.0 / _CONVERSIONS[(to, unit)]
    known = sorted({u for pair in _CONVERSIONS for u in pair})
    raise DeviceError(
        f"cannot convert {quoted(unit)} to {quoted(to)}: known units are {', '.join(known)}"
    )


def shown(value: object) -> str:
    """A JSON factor as text: [300, 1023] -> "300/1023", 0.111 -> "0.111"."""
    return "/".join(map(str, value)) if isinstance(value, list) else str(value)


def exact(value: object) -> Fraction:
    """A JSON factor as an exact fraction: 0.111 -> 111/1000, [300, 1023] -> 300/1023."""
    if isinstance(value, list) and len(value) == 2 and all(isinstance(v, int) for v in value):
        return Fraction(value[0], value[1])
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise DeviceError(
            f"a scale factor must be a number or [numerator, denominator], not {quoted(value)}"
        )
    return Fraction(repr(value)) if isinstance(value, float) else Fraction(value)


@dataclass(frozen=True)
class Scale:
    """One register step in physical units: ``factor`` ``unit`` per step."""

    unit: str
    factor: Fraction
    shown: str = field(default="", compare=False)  # the factor as the file writes it

    def factor_in(self, unit: str) -> float:
        """One step expressed in ``unit`` (e.g. the position scale in "rad")."""
        return float(self.factor) * conversion(self.unit, unit)

    def per_unit(self, unit: str) -> float:
        """Steps per one ``unit`` (e.g. position ticks per "rad")."""
        return 1.0 / self.factor_in(unit)

    def __str__(self) -> str:
        if self.factor == 1:
            return self.unit
        return f"{self.shown or self.factor} {self.unit}"


class Encoding(str, Enum):  # enum.StrEnum is Python 3.11+; this is the same for 3.10
    """How a register's bits hold a signed value."""

    UNSIGNED = "unsigned"
    SIGN_MAGNITUDE_BIT10 = "sign_magnitude_bit10"  # bits 0-9 magnitude, bit 10 set = CW (<0)
    TWOS_COMPLEMENT = "twos_complement"

    def __str__(self) -> str:
        return str(self.value)

    @property
    def direction_bit(self) -> int | None:
        """The bit that carries the sign in a sign-magnitude encoding, else None."""
        return 10 if self is Encoding.SIGN_MAGNITUDE_BIT10 else None

    @property
    def magnitude_mask(self) -> int | None:
        """The bits that carry the magnitude in a sign-magnitude encoding, else None."""
        bit = self.direction_bit
        return None if bit is None else (1 << bit) - 1

    def decode_value(self, raw: int) -> int:
        """The signed value of ``raw`` (what the register holds): CW speeds are negative."""
        bit = self.direction_bit
        if bit is None:
            return raw
        magnitude = raw & ((1 << bit) - 1)
        return -magnitude if raw >> bit & 1 else magnitude

    def encode_value(self, value: int) -> int:
        """What the register holds for the signed ``value`` (inverse of :meth:`decode_value`)."""
        bit = self.direction_bit
        if bit is None:
            return value
        return (1 << bit) | -value if value < 0 else value
