"""The bootloader's ``Checksum:`` report: read in every plausible format, matched with ours.

What the real ROBOTIS bootloader prints after an image is not documented: a sum of 8, 16
or 32 bits, in hex (with or without ``0x``, either case, padded or not) or in decimal. A
report is read as every number it can mean (:class:`Reading`: a value and its width) and
our sums are compared modulo each width. A report that reads as no number is
*unrecognised*: the caller decides whether to start the firmware anyway.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from snakebot.link.flash.errors import FlashFailed

WIDTHS = (8, 16, 32)
"""The sum widths a bootloader plausibly reports, in bits."""

_NUMBER = re.compile(r"\s*:?\s*(0[xX])?\s*([0-9A-Fa-f]+)(?![0-9A-Za-z])")
"""After the word ``Checksum``: an optional colon, an optional ``0x``, the digits, and
nothing that would make them part of a longer word."""


@dataclass(frozen=True)
class Reading:
    """One meaning of the report: ``value``, a sum of ``bits`` bits, printed in ``base``."""

    value: int
    bits: int
    base: int

    def shown(self, value: int | None = None) -> str:
        """``value`` (default: the reading's own) as this reading prints it, for messages."""
        v = self.value if value is None else value
        if self.base == 10:
            return f"{v} ({self.bits}-bit decimal)"
        return f"0x{v:0{self.bits // 4}X} ({self.bits}-bit hex)"


def _narrowest(needed_bits: int) -> int | None:
    return next((w for w in WIDTHS if w >= needed_bits), None)


def parse_report(text: str) -> tuple[Reading, ...]:
    """Every reading of ``text``, what follows ``Checksum`` on its line; () if none.

    Hex digits give the width (2 digits: 8 bits, 3 or 4: 16, 5 to 8: 32); a decimal
    number the narrowest width that holds it. Digits alone may be either base.
    """
    found = _NUMBER.match(text)
    if found is None:
        return ()
    prefix, digits = found.groups()
    readings = []
    # Padding says the width; zeros padded past 32 bits are only padding.
    hex_bits = _narrowest(4 * len(digits)) or _narrowest(4 * len(digits.lstrip("0")))
    if hex_bits is not None:
        readings.append(Reading(int(digits, 16), hex_bits, 16))
    if prefix is None and digits.isdigit():
        value = int(digits)
        dec_bits = _narrowest(value.bit_length())
        if dec_bits is not None:
            readings.append(Reading(value, dec_bits, 10))
    return tuple(readings)


@dataclass(frozen=True)
class ChecksumReport:
    """The bootloader's ``Checksum`` line: its text and what it can mean."""

    text: str  # what followed "Checksum" on the line, as received
    reply: bytes  # everything the bootloader said after the image

    @property
    def readings(self) -> tuple[Reading, ...]:
        return parse_report(self.text)

    @property
    def recognised(self) -> bool:
        return bool(self.readings)


@dataclass(frozen=True)
class ChecksumMatch:
    """How the bootloader's sum was matched."""

    value: int
    reading: Reading
    meaning: str  # which bytes the bootloader summed


def our_sums(image: bytes, sent: bytes) -> list[tuple[int, str]]:
    """The sums the bootloader may report (full width), each with the bytes it covers.

    The bootloader may sum every byte it received (the image and, when sent, the trailing
    checksum byte) or only the image: which one the real CM-530 does is not confirmed.
    """
    sums = [(sum(sent), "the sum of every byte sent")]
    if sent != image:
        sums.append((sum(image), "the sum of the image without its checksum byte"))
    return sums


def verify_checksum(image: bytes, sent: bytes, report: ChecksumReport) -> ChecksumMatch:
    """Compare a recognised report with our sums, or raise :class:`FlashError`."""
    readings = report.readings
    for reading in readings:
        for total, meaning in our_sums(image, sent):
            if total % (1 << reading.bits) == reading.value:
                return ChecksumMatch(reading.value, reading, meaning)
    first = readings[0]
    ours = " or ".join(
        f"{first.shown(t % (1 << first.bits))} ({m})" for t, m in our_sums(image, sent)
    )
    raise FlashFailed(
        f"checksum mismatch: the bootloader reports 'Checksum{report.text.rstrip()}', we "
        f"expected {ours}. Bytes were lost or changed on the way: the application was NOT "
        "started. Check the cable, press MODE or power-cycle the CM-530 and flash again"
    )


def unrecognised_message(image: bytes, sent: bytes, report: ChecksumReport) -> str:
    """The warning for a report that reads as no number, with our sums beside it."""
    ours = " or ".join(f"0x{t:08X} ({m})" for t, m in our_sums(image, sent))
    return (
        f"the bootloader's report 'Checksum{report.text.rstrip()}' is in a format snakebot "
        f"does not know, so it cannot tell whether the image arrived intact (our sums: "
        f"{ours})"
    )
