"""Servo chores on a Dynamixel bus (what people used Dynamixel Wizard for): find servos,
identify them, read and write registers by name, change a servo's ID or baud rate.

Each operation takes a :class:`~snakebot.link.transport.DxlClient` (or, for a scan over several
baud rates, an open port) and returns plain data; ``snakebot bus`` prints it. Registers,
their units and the baud formula come from the device descriptions
(:mod:`snakebot.facts.devices`, through
:class:`~snakebot.formats.protocol.ControlTable`): no address or unit factor is written here.

Values are checked before anything is sent: a read-only register, a value outside the
register's documented range, or an ID that is already taken is refused with a sentence
saying why and what to do instead.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass

import serial

from snakebot.errors import SnakebotError
from snakebot.facts import devices
from snakebot.facts.devices import Baud, DeviceError
from snakebot.formats import protocol
from snakebot.formats.protocol import (
    BROADCAST_ID,
    FRAME_RESET_S,
    MAX_ID,
    ControlTable,
    ControlTableError,
    CorruptPacket,
    DxlTimeout,
    Entry,
    ErrorFlags,
    Packet,
    PacketParser,
    Rejected,
)
from snakebot.link.transport import BusTiming, DxlClient, settings, timing
from snakebot.link.transport.portio import PortIO

BASE_MODEL = "AX-12A"
"""The table used to check names and ranges before a servo has been asked its model
(the AX-12 family shares addresses and ranges; only some defaults differ)."""

COMMON_REGISTERS = (1, 3, 4, 7, 9, 16, 34, 207)
"""The Baud Rate values the AX-12 e-Manual tabulates."""

STANDARD_REGISTERS = (0, *COMMON_REGISTERS, 103)
"""The Baud Rate values the AX and MX e-Manuals tabulate between them (each model's
fixed-rate values come from its description)."""

SCAN_RETRIES = 3
"""Further PINGs a scan gives an ID whose reply came back damaged."""

QUIET_READ_SIZE = 4096
"""Bytes one read of a quiet pause may drop (more than the line brings in the pause)."""

SETTLE_S = 0.01
"""Pause after an ID or baud change before the servo is addressed anew (it stores the
new value in EEPROM)."""


class BusCommandError(SnakebotError):
    """A servo chore that cannot be done as asked; the message says why and what to do."""


@dataclass(frozen=True)
class ServoInfo:
    """One servo found on the bus."""

    id: int
    baud: int
    model_number: int | None  # None when it answers PING but not READ
    model: str | None  # None when no device description has the model number
    firmware: int | None
    error: ErrorFlags  # the error bits of its PING reply

    @property
    def label(self) -> str:
        """The model in words: "AX-12A", "model 29", or "a device that answers PING only"."""
        if self.model_number is None:
            return "a device that answers PING only (Status Return Level 0?)"
        return self.model or f"model {self.model_number}"

    def as_dict(self) -> dict[str, object]:
        return {
            "id": self.id,
            "baud": self.baud,
            "model_number": self.model_number,
            "model": self.model,
            "firmware": self.firmware,
            "error": int(self.error),
            "error_text": self.error.describe(),
        }


def _base() -> ControlTable:
    return ControlTable.for_model(BASE_MODEL)


def model_name(number: int) -> str | None:
    """The servo model whose model number is ``number`` (12: "AX-12A"), or None."""
    try:
        return ControlTable.for_model_number(number).model
    except ControlTableError:
        return None


# -- register names and values ------------------------------------------------------------


def _squash(text: str) -> str:
    return re.sub(r"[\s_\-]+", "", text).lower()


def resolve_register(name_or_address: str, table: ControlTable | None = None) -> Entry:
    """The register called ``name_or_address``: a register name in any case, with
    spaces, '-' or '_' ("goal-position"), or the decimal or 0x address where it starts."""
    table = table or _base()
    text = name_or_address.strip()
    if re.fullmatch(r"\d+|0[xX][0-9a-fA-F]+", text):
        address = int(text, 0)
        entry = table.by_address(address)
        if entry is None:
            starts = ", ".join(f"{e.address} {e.name}" for e in table)
            raise BusCommandError(
                f"no {table.model} register starts at address {address}: registers start at "
                f"{starts}"
            )
        return entry
    wanted = _squash(text)
    for entry in table:
        if _squash(entry.name) == wanted:
            return entry
    names = ", ".join(e.name.lower().replace(" ", "-") for e in table)
    raise BusCommandError(
        f"{table.model} has no register {name_or_address!r}: use a name ({names}) or an address"
    )


def write_range(entry: Entry) -> tuple[int, int]:
    """The values ``entry`` accepts: its documented range, else the whole field."""
    low = 0 if entry.min is None else entry.min
    high = (1 << (8 * entry.size)) - 1 if entry.max is None else entry.max
    return low, high


def parse_value(entry: Entry, text: str) -> int:
    """The raw value ``text`` asks ``entry`` for: a whole number (decimal or 0x hex), or an
    amount with a unit ("30deg", "50 rpm", "0.5rad"), converted through the register's
    scale in its device description."""
    text = text.strip()
    try:
        return int(text, 0)
    except ValueError:
        pass
    m = re.fullmatch(r"([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z%/]+)", text)
    if m is None:
        raise BusCommandError(
            f"cannot read the value {text!r}: give a whole number (512, 0x200) or an amount "
            "with a unit (30deg, 50rpm)"
        )
    amount, unit = float(m.group(1)), m.group(2)
    if entry.scale is None:
        raise BusCommandError(f"{entry.name} has no unit: give its raw value, not {text!r}")
    try:
        raw = entry.from_units(amount, unit)
    except DeviceError:
        raise BusCommandError(
            f"{entry.name} is in {entry.scale.unit}: cannot convert {unit!r} "
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


def meaning(entry: Entry, value: int, table: ControlTable | None = None) -> str | None:
    """What a special value of ``entry`` stands for: the Baud Rate register's bit rate,
    the error bits of an alarm mask, 0 for Moving Speed; None for plain values."""
    table = table or _base()
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
    if "physical" in decoded:
        parts.append(f"{decoded['physical']:g} {decoded['unit']}")
    elif "unit" in decoded:
        parts.append(str(decoded["unit"]))
    return f"{decoded['value']}" + (f" ({', '.join(parts)})" if parts else "")


# -- identification and scanning -----------------------------------------------------------


def identify(client: DxlClient, servo_id: int, *, retries: int | None = None) -> ServoInfo | None:
    """PING ``servo_id`` and read its model and firmware; None if it does not answer.

    A servo reporting error bits (overheated, overloaded) is still identified: its
    flags are in :attr:`ServoInfo.error`. Damaged replies raise :class:`CorruptPacket`
    after the client's retries."""
    try:
        reply = client.ping(servo_id, check=False, retries=retries)
    except DxlTimeout:
        return None
    return _identified(client, servo_id, reply)


def _identified(client: DxlClient, servo_id: int, reply: Packet) -> ServoInfo:
    """The servo that answered PING with ``reply``: its model and firmware, read."""
    base = _base()
    start = base.by_name("Model Number").address
    fw = base.by_name("Firmware Version")
    length = fw.address + fw.size - start
    try:
        data = client.transact(
            protocol.read(servo_id, start, length), servo_id, length, check=False
        ).params
    except DxlTimeout:  # answers PING only: Status Return Level 0
        return ServoInfo(servo_id, client.baudrate, None, None, None, reply.error)
    number = int.from_bytes(data[:2], "little")
    return ServoInfo(
        id=servo_id,
        baud=client.baudrate,
        model_number=number,
        model=model_name(number),
        firmware=data[fw.address - start],
        error=reply.error,
    )


@dataclass(frozen=True)
class Probe:
    """What one ID at one baud rate gave in a scan."""

    id: int
    baud: int
    info: ServoInfo | None  # None: nothing identified
    garbled: bool = False  # every try heard only damaged replies: something is there

    def as_dict(self) -> dict[str, object]:
        return {"id": self.id, "baud": self.baud}


def longest_return_delay_us() -> float:
    """The longest Return Delay Time any servo described can be set to (an AX-12's
    254 x 2 us), or the one snakebot is told to assume if that is longer: a scan knows
    nothing of the servos' settings, so it waits this long for each reply to begin."""
    longest = settings.resolve_return_delay_us()
    for name in devices.names("servo"):
        delay = devices.load(name).register("Return Delay Time")
        if delay.scale is not None and delay.max is not None:
            longest = max(longest, delay.max * float(delay.scale.factor))
    return longest


def silence_s(client: DxlClient) -> float:
    """How long after a PING leaves the host a scan takes a silent line for a missing
    servo: the PING on the wire, :func:`longest_return_delay_us`, the first byte of a
    status packet, and the adapter's latency and the host's margin (the client's). It
    scales with the baud rate, so slow rates cost what their wire needs."""
    return timing.reply_timeout_s(
        len(protocol.ping(0)),
        1,
        client.baudrate,
        return_delay_us=longest_return_delay_us(),
        latency_s=client.timing.latency_s,
        margin_s=client.timing.margin_s,
    )


def quiet_s(bus: BusTiming) -> float:
    """How long a quiet pause lasts: the servos' frame reset and the host's margin (the
    host may be late to send, never early, so the servos' pause is at least this)."""
    return FRAME_RESET_S + bus.margin_s


def _quiet(port: serial.SerialBase, seconds: float) -> None:
    """Send nothing for ``seconds`` (reading and dropping whatever arrives), so every
    servo abandons a packet it was still waiting for. Waiting in a read, not a sleep,
    lets an emulated bus's clock run too."""
    deadline = time.monotonic() + seconds
    while (remaining := deadline - time.monotonic()) > 0:
        port.timeout = remaining
        port.read(QUIET_READ_SIZE)
    port.reset_input_buffer()


def detect_echo(port: serial.SerialBase, baud: int) -> bool:
    """Whether the line echoes the host's own bytes (a one-wire adapter), unless
    ``SNAKEBOT_ECHO`` says: a broadcast PING, which no servo answers, comes back only
    as its echo. Asked again (after a quiet pause) while what comes back is damaged.

    A scan settles this first because the client's own "auto" mode decides from the
    first answer, and on a noisy line a damaged echo can mislead it for the whole scan.
    """
    setting = settings.resolve_echo()
    if setting != "auto":
        return bool(setting)
    packet = protocol.ping(BROADCAST_ID)
    # an echo comes back before any reply would: the reply timeout covers it
    bus = DxlClient(port, baud, echo=False).timing
    wait = bus.reply_timeout_s(len(packet), 0)
    for _ in range(1 + SCAN_RETRIES):
        port.reset_input_buffer()
        port.write(packet)
        heard = b""
        deadline = time.monotonic() + wait
        while (remaining := deadline - time.monotonic()) > 0 and len(heard) < len(packet):
            port.timeout = remaining
            heard += port.read(len(packet) - len(heard))
        if not heard:
            return False
        if heard == packet:
            return True
        _quiet(port, quiet_s(bus))
    return True  # something came back every time, damaged: an echo on a noisy line


@dataclass
class _Heard:
    """What one PING's window brought: the PINGed servo's reply, a late reply from the
    ID PINGed before it, and whether anything came back damaged or incomplete."""

    reply: Packet | None = None
    late: Packet | None = None
    trouble: bool = False


class _Sweep:
    """The PINGs of a scan at one rate, back to back, for :func:`scan_probes`.

    A silent ID (the rule) costs one write and a wait that ends when :func:`silence_s`
    says: no flush, no exception, no message. The line is parsed as one
    stream rather than flushed between IDs, so a reply that turns up after its ID's
    window (an adapter or a loaded host later than the margin allowed) still counts
    for the ID it names: an ID's result is given once the next ID's window is over.

    An ID whose PING brings something damaged (a corrupted echo on a one-wire adapter,
    noise, a reply begun and never finished, two servos on one ID) gets up to
    :data:`SCAN_RETRIES` more, each after a quiet pause (:func:`quiet_s`): a damaged
    length byte leaves the servos waiting for the rest of a packet that never comes,
    and they give up on it only after a pause. If every try is damaged, the result is
    marked garbled: something is there."""

    def __init__(self, client: DxlClient, silence: float, pings: Mapping[int, bytes]) -> None:
        self.client = client
        self.silence = silence
        self.pings = pings
        self.io = PortIO(client.port)
        self.parser = PacketParser()
        self.reply_timeout = client.timing.reply_timeout_s(len(protocol.ping(0)), 0)

    def run(self, ids: Sequence[int]) -> Iterator[Probe]:
        """Each of ``ids``' results, once."""
        baud = self.client.baudrate
        pending: int | None = None  # silent so far; its reply may still come
        self.io.flush_input()
        for servo_id in ids:
            heard = self._listen(servo_id, pending)
            if heard.late is not None and pending is not None:
                yield self._found(pending, heard.late)
                pending = None
            if heard.trouble:
                yield self._retry(servo_id)
                if pending is not None:  # the damage may have been its reply
                    yield self._retry(pending)
                    pending = None
            elif heard.reply is not None:
                yield self._found(servo_id, heard.reply)
            else:
                if pending is not None:
                    yield Probe(pending, baud, None)
                pending = servo_id
                continue
            # The result above came first, so a caller that counts the bytes heard and
            # sent between results charges the silent one below with none.
            if pending is not None:
                yield Probe(pending, baud, None)
                pending = None
        if pending is not None:
            yield Probe(pending, baud, None)

    def _listen(self, servo_id: int, pending: int | None) -> _Heard:
        """PING ``servo_id`` and listen until the silence window ends or, once a reply
        has begun, its whole reply timeout."""
        packet = self.pings[servo_id]
        self.io.write(packet)  # first: what follows is done while it is on the wire
        start = time.monotonic()
        io, parser, heard = self.io, self.parser, _Heard()
        echo_due = self.client.echo is True
        deadline = start + self.silence
        unheard = len(packet) if echo_due else 0  # bytes that may come back without a reply
        while (remaining := deadline - time.monotonic()) > 0:
            # exactly what completes a reply (and the echo): one read when all goes well
            want = timing.STATUS_OVERHEAD - parser.pending + (len(packet) if echo_due else 0)
            data = io.read(want if want > 1 else 1, remaining)
            if not data:
                continue
            unheard -= len(data)
            if unheard < 0:  # a reply has begun: it gets its whole time
                deadline = start + self.reply_timeout
            for event in parser.feed(data):
                if isinstance(event, Rejected):
                    heard.trouble = True
                elif echo_due and event.encode() == packet:
                    echo_due = False  # our own PING: the first packet equal to it
                elif event.id == servo_id:
                    if event.params:  # no PING reply has parameters: not what it seems
                        heard.trouble = True
                    else:
                        heard.reply = event
                elif event.id == pending and not event.params:
                    heard.late = event
            if heard.reply is not None:
                break
        # A missing echo means the PING itself may have been damaged; bytes beyond the
        # echo that made no reply are one damaged past recognition (a collision, noise).
        heard.trouble |= echo_due or (unheard < 0 and heard.reply is None and heard.late is None)
        return heard

    def _identify(self, servo_id: int, reply: Packet) -> ServoInfo | None:
        """The servo that answered with ``reply``, its model read through the client
        (which flushes the line, so the parser starts afresh); None if that read kept
        coming back damaged."""
        try:
            return _identified(self.client, servo_id, reply)
        except CorruptPacket:
            return None
        finally:
            self.parser.reset()

    def _found(self, servo_id: int, reply: Packet) -> Probe:
        info = self._identify(servo_id, reply)
        if info is None:
            return self._retry(servo_id)
        return Probe(servo_id, self.client.baudrate, info)

    def _retry(self, servo_id: int) -> Probe:
        """The further tries of an ID whose PING (or identifying READ) came back damaged."""
        client = self.client
        for _ in range(SCAN_RETRIES):
            _quiet(client.port, quiet_s(client.timing))  # ends with a flush
            self.parser.reset()
            heard = self._listen(servo_id, None)
            if heard.trouble:
                continue
            if heard.reply is None:
                return Probe(servo_id, client.baudrate, None)
            info = self._identify(servo_id, heard.reply)
            if info is not None:
                return Probe(servo_id, client.baudrate, info)
        return Probe(servo_id, client.baudrate, None, garbled=True)


def scan_probes(
    port: serial.SerialBase, ids: Iterable[int], bauds: Sequence[int]
) -> Iterator[Probe]:
    """PING every ID in ``ids`` at each rate in ``bauds`` and identify the servos that
    answer (:class:`_Sweep` says how), yielding each result as it comes, so a caller
    can show progress and keep what was found if stopped."""
    ids = list(ids)
    pings = {servo_id: protocol.ping(servo_id) for servo_id in ids}
    echo = detect_echo(port, bauds[0]) if bauds else False
    for n, baud in enumerate(bauds):
        client = DxlClient(port, baud, echo=echo)
        if n:  # servos at this rate heard the last one's PINGs as garbage: let them reset
            _quiet(port, quiet_s(client.timing))
        yield from _Sweep(client, silence_s(client), pings).run(ids)


def scan(port: serial.SerialBase, ids: Iterable[int], bauds: Sequence[int]) -> list[ServoInfo]:
    """The servos :func:`scan_probes` identifies."""
    return [p.info for p in scan_probes(port, ids, bauds) if p.info is not None]


def parse_ids(text: str) -> list[int]:
    """ "0-253", "1,2,5-7" -> the IDs, in order, each once; refuses IDs outside 0-253."""
    ids: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        m = re.fullmatch(r"(\d+)(?:\s*-\s*(\d+))?", part)
        if m is None:
            raise BusCommandError(f"cannot read the ID range {text!r}: write e.g. 0-253 or 1,2,5-7")
        low = int(m.group(1))
        high = int(m.group(2)) if m.group(2) else low
        if low > high or high > MAX_ID:
            raise BusCommandError(
                f"ID range {part!r} is not within 0-{MAX_ID} (low to high); "
                f"{BROADCAST_ID} is the broadcast ID, never a servo's"
            )
        ids += [i for i in range(low, high + 1) if i not in ids]
    if not ids:
        raise BusCommandError(f"no IDs in {text!r}: write e.g. 0-253 or 1,2,5-7")
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
            f"cannot read the baud rates {text!r}: write e.g. 1000000,57600, common or all"
        )
    for bps in bauds:  # a rate no servo runs at would wait seconds per ID for nothing
        check_bus_baud(bps)
    return bauds


# -- reading and writing registers ------------------------------------------------------


def servo_table(client: DxlClient, servo_id: int) -> ControlTable:
    """The control table of the servo at ``servo_id``, from its Model Number."""
    address = _base().by_name("Model Number").address
    # Confirmed: the model decides which table every later register name is read from.
    number = int.from_bytes(client.read_confirmed(servo_id, address, 2), "little")
    try:
        return ControlTable.for_model_number(number)
    except ControlTableError:
        known = ", ".join(
            f"{ControlTable.for_model(m).model_number} ({m})" for m in ControlTable.models()
        )
        raise BusCommandError(
            f"servo {servo_id} reports model number {number}, which snakebot has no control "
            f"table for (known: {known}): its registers may sit elsewhere, so nothing was "
            "read or written by name"
        ) from None


def read_registers(
    client: DxlClient, servo_id: int, entries: Sequence[Entry]
) -> tuple[ControlTable, list[dict[str, object]]]:
    """Read ``entries`` (all registers if empty) in one READ; decoded, in address order."""
    table = servo_table(client, servo_id)
    chosen = sorted({table.by_name(e.name) for e in entries} or set(table), key=lambda e: e.address)
    start = chosen[0].address
    end = max(e.address + e.size for e in chosen)
    data = client.read(servo_id, start, end - start)
    values = []
    for entry in chosen:
        offset = entry.address - start
        raw = int.from_bytes(data[offset : offset + entry.size], "little")
        values.append(decode(entry, raw, table))
    return table, values


def write_register(client: DxlClient, servo_id: int, entry: Entry, value: int) -> int | None:
    """Write ``value`` to ``entry`` after checking it; returns the value read back (None if
    the servo's Status Return Level does not answer READs)."""
    check_write(entry, value)
    table = servo_table(client, servo_id)
    entry = table.by_name(entry.name)
    client.write(servo_id, entry.address, value.to_bytes(entry.size, "little"))
    if client.status_return_level(servo_id) < 1:
        return None
    read_back = client.read_confirmed(servo_id, entry.address, entry.size)  # it verifies
    return int.from_bytes(read_back, "little")


# -- ID and baud rate ---------------------------------------------------------------------


def _send_and_settle(client: DxlClient, packet: bytes) -> None:
    """Send an EEPROM change without waiting for its status (which may come from the new
    ID or at the old rate), let the reply pass, and discard it."""
    client.send(packet)
    time.sleep(client.timing.reply_timeout_s(len(packet), 0) + SETTLE_S)
    client.port.reset_input_buffer()


def set_id(client: DxlClient, old: int, new: int) -> ServoInfo:
    """Give the servo at ``old`` the ID ``new``; refuses an ID another device answers to.
    Returns the servo as found at its new ID."""
    for what, servo_id in (("current", old), ("new", new)):
        if not 0 <= servo_id <= MAX_ID:
            raise BusCommandError(
                f"the {what} ID {servo_id} is not a servo ID: use 0-{MAX_ID} "
                f"({BROADCAST_ID} is broadcast)"
            )
    if old == new:
        raise BusCommandError(f"servo {old} already has ID {new}: nothing to do")
    check_write(_base().by_name("ID"), new)
    if identify(client, old) is None:
        raise BusCommandError(
            f"no servo answers at ID {old} at {client.baudrate} baud: check the ID and baud "
            "rate with snakebot bus scan"
        )
    taken = identify(client, new)
    if taken is not None:
        raise BusCommandError(
            f"ID {new} is already taken on this bus ({taken.label} answers there): two "
            "servos with one ID garble each other's replies. Pick a free ID (snakebot bus "
            "scan lists the IDs in use)"
        )
    address = servo_table(client, old).by_name("ID").address
    _send_and_settle(client, protocol.write(old, address, bytes([new])))
    moved = identify(client, new)
    if moved is None:
        still = identify(client, old) is not None
        raise BusCommandError(
            f"servo {old} did not take ID {new}"
            + (
                ": it still answers at its old ID, so it refused the write (is its EEPROM "
                "locked? Lock is cleared by a power cycle)"
                if still
                else " and no longer answers at either ID: scan the bus (snakebot bus scan)"
            )
        )
    return moved


def _baud() -> Baud:
    return _base().device.require_baud()


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
    factory = _base().by_name("Baud Rate").default
    assert factory is not None  # the AX-12A's description gives it
    first = int(baud_from_register(factory))
    return [first, *sorted(rates - {first}, reverse=True)]


def slowest_bps() -> int:
    """The slowest bit rate a described device answers at: its slowest tabulated rate,
    less the clock error the device tolerates (so a nominal 9600 passes for 9615)."""
    return int(min(all_bauds()) * (1.0 - _baud().tolerance))


@dataclass(frozen=True)
class BaudChange:
    """The outcome of :func:`set_baud`."""

    id: int
    register: int
    servo_baud: float  # what the servo now runs at
    host_baud: int  # the rate the host reopened at to check
    verified: bool


def set_baud(client: DxlClient, servo_id: int, register: int, host_baud: int) -> BaudChange:
    """Write Baud Rate ``register`` to ``servo_id``, then reopen the port at ``host_baud``
    and PING the servo there. Raises :class:`BusCommandError` if it does not answer."""
    entry = _base().by_name("Baud Rate")
    check_write(entry, register)
    if identify(client, servo_id) is None:
        raise BusCommandError(
            f"no servo answers at ID {servo_id} at {client.baudrate} baud: find it first "
            "(snakebot bus scan --bauds common)"
        )
    old_baud = client.baudrate
    address = servo_table(client, servo_id).by_name("Baud Rate").address
    _send_and_settle(client, protocol.write(servo_id, address, bytes([register])))
    if identify(DxlClient(client.port, host_baud), servo_id) is not None:
        return BaudChange(servo_id, register, baud_from_register(register), host_baud, True)
    still = identify(DxlClient(client.port, old_baud), servo_id) is not None
    raise BusCommandError(
        f"servo {servo_id} does not answer at {host_baud} baud after the change"
        + (
            f": it still answers at {old_baud}, so it refused the write (is its EEPROM "
            "locked? Lock is cleared by a power cycle)"
            if still
            else f" nor at {old_baud}: find it with snakebot bus scan --ids {servo_id} "
            "--bauds common"
        )
    )
