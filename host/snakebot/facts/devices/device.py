"""A device on a Dynamixel bus: its control table and the facts a program needs to talk
to it (model number, where Status Return Level lives, the baud formula, the position
range)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field, replace

from snakebot.errors import quoted
from snakebot.facts.devices.errors import DeviceError
from snakebot.facts.devices.register import Register
from snakebot.facts.devices.units import Scale


def find(registers: tuple[Register, ...], name: str, missing: str) -> Register:
    """The register called ``name`` (case-insensitive) among ``registers``; DeviceError
    starting with ``missing`` and listing the known names if there is none."""
    key = name.strip().lower()
    for reg in registers:
        if reg.name.lower() == key:
            return reg
    known = ", ".join(r.name for r in registers)
    raise DeviceError(f"{missing} {quoted(name)}: known are {known}")


@dataclass(frozen=True)
class Baud:
    """The bit rate each Baud Rate register value selects: ``clock_hz / (value + 1)``,
    except the values in ``fixed``, which name their rate outright. ``tolerance``: how
    far (a fraction) the device's rate may be from the host's and still be understood."""

    register: Register
    clock_hz: int
    fixed: dict[int, int] = field(default_factory=dict)
    tolerance: float = 0.0

    def rate(self, value: int) -> float:
        """The bit rate of register ``value``; DeviceError outside the register's range."""
        low, high = self.register.value_range()
        if not low <= value <= high:
            raise DeviceError(f"{self.register.name} takes {low}..{high}, not {value}")
        return float(self.fixed.get(value, self.clock_hz / (value + 1)))

    def values(self) -> range:
        """Every register value."""
        low, high = self.register.value_range()
        return range(low, high + 1)

    def value_for(self, bps: float, tolerance: float | None = None) -> int | None:
        """The register value whose rate is within ``tolerance`` (a fraction; the
        device's own by default) of ``bps``, the nearest if several are; None if none is."""
        try:
            bps = float(bps)
        except OverflowError:  # an integer beyond any float: beyond every device's rate
            return None
        if bps <= 0:
            return None
        if tolerance is None:
            tolerance = self.tolerance
        best = min(self.values(), key=lambda v: abs(self.rate(v) - bps))
        return best if abs(self.rate(best) - bps) <= tolerance * bps else None

    def describe(self) -> str:
        """The formula in words, for messages."""
        low, high = self.register.value_range()
        text = f"{self.clock_hz} / (n + 1) for {self.register.name} n = {low}..{high}"
        if self.fixed:
            text += ", except " + ", ".join(f"n = {v}: {r}" for v, r in self.fixed.items())
        return text


@dataclass(frozen=True)
class Position:
    """The joint-position facts: the goal register, its range, centre and step."""

    register: Register
    centre: int

    @property
    def scale(self) -> Scale:
        assert self.register.scale is not None  # the loader checks it
        return self.register.scale

    @property
    def range(self) -> tuple[int, int]:
        """(lowest, highest) tick a goal may take."""
        return self.register.value_range()

    @property
    def span_deg(self) -> float:
        """Degrees from the lowest to the highest tick."""
        low, high = self.range
        return (high - low) * self.scale.factor_in("deg")

    @property
    def rad_per_tick(self) -> float:
        return self.scale.factor_in("rad")

    @property
    def ticks_per_rad(self) -> float:
        return self.scale.per_unit("rad")


@dataclass(frozen=True)
class ServoWindow:
    """The controller's window onto its roster: ``records`` records of ``record_size``
    bytes from ``address``; each field's address is its offset in a record."""

    address: int
    record_size: int
    records: int
    fields: tuple[Register, ...]


@dataclass(frozen=True)
class Page:
    """A page of the controller's window: what addresses ``base`` .. show while Window
    Page holds ``number``. Each field's address is its offset from ``base``."""

    number: int
    name: str
    description: str
    base: int
    fields: tuple[Register, ...]

    def field(self, name: str) -> Register:
        """The field called ``name`` (its address is the offset in the page)."""
        return find(self.fields, name, f"page {self.name} has no field")

    def register(self, name: str) -> Register:
        """Field ``name`` as a register at its absolute address (while this page is shown)."""
        reg = self.field(name)
        return replace(reg, address=self.base + reg.address)


@dataclass(frozen=True)
class Device:
    """One device: a servo model or the snakebot controller."""

    name: str
    kind: str  # "servo" or "controller"
    protocol: str  # "1.0"
    model_number: int
    description: str
    table_size: int
    registers: tuple[Register, ...]
    scales: dict[str, Scale]
    eeprom_end: int | None = None  # first RAM address; None for a table without areas
    status_return_level: str | None = None  # the register's name; None: the device has none
    baud: Baud | None = None  # None: a fixed rate (the controller's PC link)
    position: Position | None = None
    based_on: str | None = None  # the device this one is a variant of
    servo_model: str | None = None  # the controller: the servo model it drives
    limits: dict[str, int] = field(default_factory=dict)
    max_speed_rpm: float | None = None  # no-load joint speed (a servo's datasheet fact)
    servo_window: ServoWindow | None = None
    pages: tuple[Page, ...] = ()  # the window's described pages beyond the servo records
    enums: dict[str, dict[str, int]] = field(default_factory=dict)
    flags: tuple[str, ...] = ()  # the enums whose values are bit flags

    def __iter__(self) -> Iterator[Register]:
        return iter(self.registers)

    def register(self, name: str) -> Register:
        """The register called ``name`` (case-insensitive), e.g. "Goal Position"."""
        return find(self.registers, name, f"{self.name} has no register")

    def page(self, name: str | int) -> Page:
        """The window page called ``name`` (case-insensitive) or numbered ``name``."""
        for page in self.pages:
            if page.number == name or (isinstance(name, str) and page.name.lower() == name.lower()):
                return page
        known = ", ".join(f"{p.number} ({p.name})" for p in self.pages)
        raise DeviceError(f"{self.name} has no window page {quoted(name)}: known are {known}")

    def page_of(self, name: str) -> Page | None:
        """The window page holding the field called ``name``, or None (no page has it)."""
        key = name.strip().lower()
        for page in self.pages:
            if any(f.name.lower() == key for f in page.fields):
                return page
        return None

    def span(self, first: str, last: str) -> tuple[int, int]:
        """(address, length) of the bytes from register ``first`` through ``last``, for a
        READ or SYNC_WRITE that covers several registers at once."""
        start, end = self.register(first).address, self.register(last).end
        if end <= start:
            raise DeviceError(f"{self.name}: {last} does not come after {first}")
        return start, end - start

    def at(self, address: int) -> Register | None:
        """The register starting at ``address``, or None (reserved or mid-register)."""
        for reg in self.registers:
            if reg.address == address:
                return reg
        return None

    def covering(self, address: int) -> Register | None:
        """The register holding byte ``address``, or None (reserved)."""
        for reg in self.registers:
            if reg.address <= address < reg.end:
                return reg
        return None

    def scale(self, name: str) -> Scale:
        """The named scale ("position", "speed", ...)."""
        try:
            return self.scales[name]
        except KeyError:
            known = ", ".join(self.scales)
            raise DeviceError(
                f"{self.name} has no scale {quoted(name)}: known are {known}"
            ) from None

    @property
    def status_return_level_address(self) -> int | None:
        """Where Status Return Level lives, or None when the device has none."""
        if self.status_return_level is None:
            return None
        return self.register(self.status_return_level).address

    def require_position(self) -> Position:
        """The position facts; DeviceError for a device that has none (the controller)."""
        if self.position is None:
            raise DeviceError(f"{self.name} is not a servo: it has no position")
        return self.position

    def require_baud(self) -> Baud:
        """The baud formula; DeviceError for a device with a fixed rate."""
        if self.baud is None:
            raise DeviceError(f"{self.name} has no Baud Rate register: its rate is fixed")
        return self.baud

    def default_image(self) -> bytes:
        """The table's bytes after a factory reset: defaults (or emulator defaults) in
        place, little-endian; reserved and default-less registers are 0."""
        image = bytearray(self.table_size)
        for reg in self.registers:
            value = reg.default if reg.default is not None else reg.emulator_default
            if value is not None and reg.size <= 4:
                image[reg.address : reg.end] = value.to_bytes(reg.size, "little", signed=reg.signed)
        return bytes(image)
