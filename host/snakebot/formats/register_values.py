"""Register values as people write and read them: a register found by name or address, a
value parsed from text in the register's units and checked against its range, a raw value
decoded into units and words, servo IDs and baud rates parsed from text, and the baud
register's formula. Everything comes from the device descriptions
(:mod:`snakebot.facts.devices`, through :class:`~snakebot.formats.protocol.ControlTable`):
no address or unit factor is written here. No I/O."""

from __future__ import annotations

import math
import re

from snakebot.errors import InputError, quoted
from snakebot.facts import devices
from snakebot.facts.devices import Baud, DeviceError
from snakebot.formats.protocol import (
    BROADCAST_ID,
    MAX_ID,
    ControlTable,
    ControlTableError,
    Entry,
    ErrorFlags,
)

BASE_MODEL = "AX-12A"


"""The table used to check names and ranges before a servo has been asked its model
(the AX-12 family shares addresses and ranges; only some defaults differ)."""


COMMON_REGISTERS = (1, 3, 4, 7, 9, 16, 34, 207)


"""The Baud Rate values the AX-12 e-Manual tabulates."""


STANDARD_REGISTERS = (0, *COMMON_REGISTERS, 103)


"""The Baud Rate values the AX and MX e-Manuals tabulate between them (each model's
fixed-rate values come from its description)."""


class BusCommandError(InputError):
    """A servo chore that cannot be done as asked; the message says why and what to do."""


def base_table() -> ControlTable:
    return ControlTable.for_model(BASE_MODEL)


def model_name(number: int) -> str | None:
    """The servo model whose model number is ``number`` (12: "AX-12A"), or None."""
    try:
        return ControlTable.for_model_number(number).model
    except ControlTableError:
        return None


def _squash(text: str) -> str:
    return re.sub(r"[\s_\-]+", "", text).lower()


def resolve_register(name_or_address: str, table: ControlTable | None = None) -> Entry:
    """The register called ``name_or_address``: a register name in any case, with
    spaces, '-' or '_' ("goal-position"), or the decimal or 0x address where it starts."""
    table = table or base_table()
    text = name_or_address.strip()
    if re.fullmatch(r"\d+|0[xX][0-9a-fA-F]+", text):
        hexadecimal = text[:2].lower() == "0x"
        # int() refuses 4300 digits and more; no address has more than a few
        address = int(text, 16 if hexadecimal else 10) if len(text) <= 12 else None
        entry = None if address is None else table.by_address(address)
        if entry is None:
            starts = ", ".join(f"{e.address} {e.name}" for e in table)
            raise BusCommandError(
                f"no {table.model} register starts at address "
                f"{quoted(text) if address is None else address}: registers start at {starts}"
            )
        return entry
    wanted = _squash(text)
    for entry in table:
        if _squash(entry.name) == wanted:
            return entry
    names = ", ".join(e.name.lower().replace(" ", "-") for e in table)
    raise BusCommandError(
        f"{table.model} has no register {quoted(name_or_address)}: use a name ({names}) or an "
        "address"
    )


def write_range(entry: Entry) -> tuple[int, int]:
    """The values ``entry`` accepts: its documented range, else the whole field."""
    low = 0 if entry.min is None else entry.min
    high = (1 << (8 * entry.size)) - 1 if entry.max is None else entry.max
    return low, high


MAX_AMOUNT = 1e9
"""No register holds more than 16 bits: an amount beyond this (1e400s, an infinity) is
refused before it is converted."""
DIAL_UNITS = {"absdeg": "deg", "absrad": "rad"}
"""Units of a position on the servo's own dial, 0 at one end of its travel: an AX-12's
0-300 degrees, as ROBOTIS's Dynamixel Wizard shows them (tick = degrees / 0.293)."""

ANGLE_UNITS = ("deg", "rad")
"""Units of a position as an angle from the servo's centre (an AX-12's tick 512)."""


def is_position(entry: Entry, table: ControlTable | None = None) -> bool:
    """Whether ``entry`` holds a servo position (Goal Position, Present Position, the
    angle limits): a register on the position's scale that takes no negative value (a
    signed register on that scale, such as the controller's Steering Offset, holds a
    difference of positions, not a position)."""
    position = (table or base_table()).device.position
    return (
        position is not None
        and entry.scale is not None
        and entry.scale == position.scale
        and write_range(entry)[0] >= 0
    )


def position_centre(table: ControlTable | None = None) -> int:
    """The servo's centre tick (512 on an AX-12): where an angle of 0 points."""
    return (table or base_table()).device.require_position().centre


def split_amount(text: str) -> tuple[float, str] | None:
    """``"30deg"`` as (30.0, "deg"), ``"-0.5 rad"`` as (-0.5, "rad"); None if ``text`` is
    not a number followed by a unit."""
    m = re.fullmatch(r"([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z%/°]+)", text.strip())
    if m is None:
        return None
    return float(m.group(1)), {"°": "deg"}.get(m.group(2), m.group(2))


def parse_value(entry: Entry, text: str) -> int:
    """The raw value ``text`` asks ``entry`` for: a whole number (decimal or 0x hex), or an
    amount with a unit ("30deg", "50 rpm", "0.5rad"), converted through the register's
    scale in its device description.

    A position (:func:`is_position`) in ``deg`` or ``rad`` is an angle from the servo's
    centre, as joints are described: ``30deg`` is 30 degrees to the counter-clockwise
    side of tick 512 (tick 614), ``-30deg`` as far to the other side. The servo's own
    0-300 degree dial (Dynamixel Wizard's numbers) is ``absdeg``: ``150absdeg`` is tick
    512. Raw ticks are whole numbers."""
    text = text.strip()
    try:
        return int(text, 0)
    except ValueError:
        pass
    amount_unit = split_amount(text)
    if amount_unit is not None and is_position(entry):
        return _position_value(entry, text, *amount_unit)
    m = re.fullmatch(r"([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z%/]+)", text)
    if m is None:
        raise BusCommandError(
            f"cannot read the value {quoted(text)}: give a whole number (512, 0x200) or an amount "
            "with a unit (30deg, 50rpm)"
        )
    amount, unit = float(m.group(1)), m.group(2)
    if not math.isfinite(amount) or abs(amount) > MAX_AMOUNT:
        raise BusCommandError(
            f"{quoted(text)} is out of range for {entry.name}: give an amount within "
            f"+-{MAX_AMOUNT:g} (the register's range is far smaller)"
        )
    if entry.scale is None:
        raise BusCommandError(f"{entry.name} has no unit: give its raw value, not {quoted(text)}")
    try:
        raw = entry.from_units(amount, unit)
    except DeviceError:
        raise BusCommandError(
            f"{entry.name} is in {entry.scale.unit}: cannot convert {quoted(unit)} "
            f"(give e.g. {amount:g}{entry.scale.unit})"
        ) from None
    if raw == 0 and entry.name in ZERO_MEANS and amount != 0:
        raise BusCommandError(
            f"{text} is below one step of {entry.name} ({entry.scale}), and 0 would mean "
            f"{ZERO_MEANS[entry.name]}: give a larger amount"
        )
    if raw == 0 and entry.name in ZERO_MEANS:
        raise BusCommandError(
            f"{entry.name} 0 means {ZERO_MEANS[entry.name]}, not {text}: write the raw 0 if "
            "that is what you want"
        )
    return raw


def _position_value(entry: Entry, text: str, amount: float, unit: str) -> int:
    """A position written as an angle from the centre (deg, rad) or on the dial (absdeg,
    absrad), in ticks; refused outside the register's range with the nearest angle."""
    if unit in DIAL_UNITS:
        raw = entry.from_units(amount, DIAL_UNITS[unit])
    elif unit in ANGLE_UNITS:
        raw = position_centre() + entry.from_units(amount, unit) - entry.from_units(0.0, unit)
    else:
        raise BusCommandError(
            f"{entry.name} is a position: give an angle from the centre (30deg, -0.5rad), "
            "a position on the servo's 0-300 dial (150absdeg) or raw ticks (512), not "
            f"{quoted(text)}"
        )
    low, high = write_range(entry)
    if not low <= raw <= high:
        centre = position_centre()
        span = (
            f"{entry.to_units(low, 'deg'):g}-{entry.to_units(high, 'deg'):g}absdeg"
            if unit in DIAL_UNITS
            else f"{entry.to_units(low - centre, 'deg'):+.1f}deg to "
            f"{entry.to_units(high - centre, 'deg'):+.1f}deg from the centre"
        )
        raise BusCommandError(
            f"{text} is outside {entry.name}'s travel ({span}, ticks {low}-{high})"
        )
    return raw


def check_write(entry: Entry, value: int) -> None:
    """Refuse a write the servo would reject, before it is sent."""
    if not entry.writable:
        raise BusCommandError(
            f"{entry.name} (address {entry.address}) is read-only: the servo only reports it"
        )
    low, high = write_range(entry)
    if not low <= value <= high:
        extra = f" ({entry.note})" if entry.note else ""
        raise BusCommandError(f"{entry.name} takes {low}-{high}, not {value}{extra}")


ERROR_BIT_REGISTERS = ("Alarm LED", "Shutdown")


"""Registers holding a mask of the status packet's error bits."""


ZERO_MEANS = {"Moving Speed": "maximum speed: no speed control"}


"""Registers where 0 is not the scale's zero (the e-Manual's note, in the descriptions)."""


WRITTEN_ELSEWHERE = {"ID": "set-id", "Baud Rate": "set-baud"}
"""Registers a plain write must not change: the command that changes each and checks it."""


def parse_write(register: str, value: str, number: int | None = None) -> tuple[Entry, int]:
    """The register named ``register`` and the raw ``value`` for it (a number, or an
    amount in a unit its scale converts; ``number`` when the caller converted it already,
    e.g. a joint's angle), refused if a plain write may not set it: read only, out of its
    range, or an ID or baud rate (which have their own commands)."""
    entry = resolve_register(register)
    if number is None:
        number = parse_value(entry, value)
    redirect = WRITTEN_ELSEWHERE.get(entry.name)
    if redirect:
        raise BusCommandError(
            f"change {entry.name} with `snakebot bus {redirect}`, which checks the result "
            "(and, for an ID, that no other servo has it)"
        )
    check_write(entry, number)
    return entry, number


def meaning(entry: Entry, value: int, table: ControlTable | None = None) -> str | None:
    """What a special value of ``entry`` stands for: the Baud Rate register's bit rate,
    the error bits of an alarm mask, 0 for Moving Speed; None for plain values."""
    table = table or base_table()
    if entry.name == "Baud Rate" and table.device.baud is not None:
        return f"{table.device.baud.rate(value):.0f} bit/s"
    if entry.name in ERROR_BIT_REGISTERS:
        return ErrorFlags(value).describe()
    if value == 0 and entry.name in ZERO_MEANS:
        return ZERO_MEANS[entry.name]
    return None


def decode(entry: Entry, value: int, table: ControlTable | None = None) -> dict[str, object]:
    """``value`` of ``entry`` in words: its unit and, where the register has a scale, the
    physical value; direction-bit registers split into magnitude and direction; special
    values (:func:`meaning`) in words."""
    out: dict[str, object] = {
        "name": entry.name,
        "address": entry.address,
        "size": entry.size,
        "value": value,
        "access": entry.access,
        "area": entry.area,
    }
    magnitude = value
    mask = entry.encoding.magnitude_mask
    # a writable direction-bit register (Moving Speed) has the bit only in wheel mode
    if mask is not None and (not entry.writable or value > mask):
        magnitude = value & mask
        out["direction"] = "CW" if entry.value(value) < 0 else "CCW"
        out["magnitude"] = magnitude
    scale = entry.scale
    if scale is not None:
        # as many decimals as one step needs
        digits = max(0, -math.floor(math.log10(float(scale.factor))))
        out["physical"] = round(magnitude * float(scale.factor), digits)
        out["unit"] = scale.unit
        if is_position(entry, table):
            # the angle from the centre, as `bus write` takes it (physical: the 0-300 dial)
            centre = position_centre(table)
            out["from_centre_deg"] = round((magnitude - centre) * scale.factor_in("deg"), digits)
    said = meaning(entry, value, table)
    if said is not None:
        out["meaning"] = said
    return out


def describe_value(decoded: dict[str, object]) -> str:
    """A decoded value as text: "512 (150.016 deg)", "1124 (100 CW, 9.8 % of ...)"."""
    parts = []
    if "meaning" in decoded:
        return f"{decoded['value']} ({decoded['meaning']})"
    if decoded.get("magnitude"):
        parts.append(f"{decoded['magnitude']} {decoded['direction']}")
    if "from_centre_deg" in decoded:
        parts.append(
            f"{decoded['from_centre_deg']:+g} deg from the centre, "
            f"{decoded['physical']:g} deg on the 0-300 dial"
        )
    elif "physical" in decoded:
        parts.append(f"{decoded['physical']:g} {decoded['unit']}")
    elif "unit" in decoded:
        parts.append(str(decoded["unit"]))
    return f"{decoded['value']}" + (f" ({', '.join(parts)})" if parts else "")


def parse_ids(text: str) -> list[int]:
    """ "0-253", "1,2,5-7" -> the IDs, in order, each once; refuses IDs outside 0-253."""
    ids: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        m = re.fullmatch(r"(\d+)(?:\s*-\s*(\d+))?", part)
        if m is None:
            raise BusCommandError(
                f"cannot read the ID range {quoted(text)}: write e.g. 0-253 or 1,2,5-7"
            )
        # int() refuses 4300 digits and more: past 9, a number is simply out of range
        low, high = (int(d) if len(d) <= 9 else MAX_ID + 1 for d in m.group(1, 2 if m[2] else 1))
        if low > high or high > MAX_ID:
            raise BusCommandError(
                f"ID range {quoted(part)} is not within 0-{MAX_ID} (low to high); "
                f"{BROADCAST_ID} is the broadcast ID, never a servo's"
            )
        ids += [i for i in range(low, high + 1) if i not in ids]
    if not ids:
        raise BusCommandError(f"no IDs in {quoted(text)}: write e.g. 0-253 or 1,2,5-7")
    return ids


def parse_bauds(text: str) -> list[int]:
    """ "1000000,57600" -> rates; "common" -> :data:`COMMON_BAUDS`; "all" ->
    :func:`all_bauds`."""
    word = text.strip().lower()
    if word == "common":
        return list(COMMON_BAUDS)
    if word == "all":
        return all_bauds()
    try:
        bauds = [int(float(b)) for b in text.split(",") if b.strip()]
    except (ValueError, OverflowError):
        bauds = []
    if not bauds or any(b <= 0 for b in bauds):
        raise BusCommandError(
            f"cannot read the baud rates {quoted(text)}: write e.g. 1000000,57600, common or all"
        )
    for bps in bauds:  # a rate no servo runs at would wait seconds per ID for nothing
        check_bus_baud(bps)
    return bauds


def _baud() -> Baud:
    return base_table().device.require_baud()


COMMON_BAUDS = tuple(int(_baud().rate(n)) for n in COMMON_REGISTERS)


"""The rates of :data:`COMMON_REGISTERS`."""


def baud_register(bps: float) -> int:
    """The Baud Rate register value whose rate (the device's baud formula) is within
    the servo's UART tolerance of ``bps``."""
    value = _baud().value_for(bps)
    if value is not None:
        return value
    examples = ", ".join(
        f"{rate} (n={n})" for n, rate in zip(COMMON_REGISTERS, COMMON_BAUDS, strict=True)
    )
    raise BusCommandError(
        f"an AX-12 cannot run at {bps:g} bit/s: its rate is {_baud().describe()}, e.g. {examples}"
    )


def baud_setting(rate: float | None, register: int | None) -> tuple[int, int]:
    """The Baud Rate register value and the host's rate for a servo's new baud rate,
    given as a rate in bit/s or as the register value (exactly one of them)."""
    if (rate is None) == (register is None):
        raise BusCommandError(
            "give either the rate (bit/s) or the Baud Rate register value, e.g. 500000 or 3"
        ).about("rate", "register")
    if register is None:
        assert rate is not None
        return baud_register(rate), round(rate)
    return register, round(baud_from_register(register))


def check_bus_baud(bps: int) -> None:
    """BusCommandError unless some servo described runs at ``bps`` (within its UART's
    tolerance): a rate none does finds nothing, and at a few bits a second every
    unanswered packet would wait for seconds."""
    for name in devices.names("servo"):
        baud = devices.load(name).baud
        if baud is not None and baud.value_for(bps) is not None:  # fixed rates included
            return
    examples = ", ".join(str(rate) for rate in COMMON_BAUDS)
    raise BusCommandError(
        f"no Dynamixel servo described runs at {bps} bit/s (an AX-12's rate is "
        f"{_baud().describe()}): give one of the servos' rates, e.g. {examples}"
    )


def baud_from_register(value: int) -> float:
    """The AX-12's bit rate for Baud Rate register ``value``."""
    return _baud().rate(value)


def all_bauds() -> list[int]:
    """Every rate the AX and MX servos described are tabulated at (:data:`STANDARD_REGISTERS`
    through each model's baud formula, and its fixed rates), each once, the factory
    rate first and the rest fastest first."""
    rates: set[int] = set()
    for name in devices.names("servo"):
        baud = devices.load(name).baud
        if baud is None:
            continue
        values = [v for v in STANDARD_REGISTERS if v in baud.values()] + list(baud.fixed)
        rates.update(int(baud.rate(v)) for v in values)
    factory = base_table().by_name("Baud Rate").default
    assert factory is not None  # the AX-12A's description gives it
    first = int(baud_from_register(factory))
    return [first, *sorted(rates - {first}, reverse=True)]


def slowest_bps() -> int:
    """The slowest bit rate a described device answers at: its slowest tabulated rate,
    less the clock error the device tolerates (so a nominal 9600 passes for 9615)."""
    return int(min(all_bauds()) * (1.0 - _baud().tolerance))


def fastest_bps() -> int:
    """The fastest bit rate a described device answers at: its fastest tabulated rate,
    plus the clock error the device tolerates."""
    return int(max(all_bauds()) * (1.0 + _baud().tolerance))
