"""Bring-up checks for `snakebot doctor`: each says ok, warn, fail or skip, what it saw,
and what to do. The ranges come from the devices' own registers and descriptions (a
servo's voltage and temperature limits, the controller's model number and version)."""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import serial

from snakebot.errors import SnakebotError
from snakebot.facts.boards import PC_LINK_BAUD
from snakebot.formats import register_values
from snakebot.formats.protocol import ControlTable, CorruptPacket, DxlTimeout, ServoError, read
from snakebot.link.bus import scan as bus_scan
from snakebot.link.controller import load as load_controller
from snakebot.link.controller.client import ControllerClient
from snakebot.link.flash.bootloader import (
    RESET_HINT,
    enter_bootloader,
    first_line,
    start_application,
)
from snakebot.link.flash.settings import FlashTimeouts
from snakebot.link.transport import DxlClient, open_port, settings
from snakebot.link.transport import adapter as transport_adapter

TTY_SYSFS = Path("/sys/class/tty")
"""Where Linux lists terminals; one backed by hardware (a USB adapter, a UART) has a
``device`` link there, a pseudo-terminal (an emulator's) has none."""

ANY_BOARD = "any"
"""``--board`` value that accepts whichever board answers."""

NO_BOARD = "NONE"
"""The Board value of a controller that names no board."""

HARDWARE_BOARD = "CM530"
"""The board a real adapter should lead to."""

FAST_LATENCY_MS = 2
"""A latency timer at most this many milliseconds keeps replies prompt."""

TEMPERATURE_MARGIN = 10
"""Degrees below a servo's Temperature Limit where a warning starts."""

SERVO_REGISTERS = (
    "Return Delay Time",
    "Temperature Limit",
    "Min Voltage Limit",
    "Max Voltage Limit",
    "Max Torque",
    "Torque Limit",
    "Present Voltage",
    "Present Temperature",
)


@dataclass(frozen=True)
class Check:
    """One check's outcome."""

    name: str
    verdict: str  # "ok", "warn", "fail" or "skip"
    detail: str  # what was seen
    fix: str = ""  # what to do (empty when ok)

    def as_dict(self) -> dict[str, str]:
        return asdict(self)


def adapter(port: str, sysfs: Path = transport_adapter.SYSFS_USB_SERIAL) -> Check:
    """The USB adapter's latency timer, when the port is a USB-serial device."""
    name = "adapter"
    if "://" in port:
        return Check(name, "skip", f"{port} is not a serial device")
    device = Path(os.path.realpath(port)).name
    ms = transport_adapter.latency_timer_ms(port, sysfs)
    if ms is None:
        return Check(name, "skip", f"{device} has no latency timer (not an FTDI adapter)")
    if ms <= FAST_LATENCY_MS:
        return Check(name, "ok", f"{device}: latency timer {ms} ms")
    return Check(
        name,
        "warn",
        f"{device}: latency timer {ms} ms, so every reply may wait that long in the adapter "
        "(snakebot waits for it, and a scan pays it for every silent ID)",
        transport_adapter.lowering_fix(port, sysfs),
    )


@dataclass(frozen=True)
class ControllerFound:
    """The controller's checks, and the board it named (lower case; None if unread)."""

    checks: list[Check]
    board: str | None = None


def board_names() -> list[str]:
    """The boards a controller may name, in lower case (``--board`` takes them)."""
    names = load_controller().enums["Board"]
    return [n.lower() for n in names if n != NO_BOARD]


def on_hardware(port: str, sysfs: Path = TTY_SYSFS) -> bool:
    """Whether ``port`` is a terminal backed by hardware (not a URL, not a pty)."""
    if "://" in port:
        return False
    return (sysfs / Path(os.path.realpath(port)).name / "device").exists()


def controller(
    port: str,
    controller_id: int,
    expected_board: str = ANY_BOARD,
    baud: int = PC_LINK_BAUD,
) -> ControllerFound | None:
    """The controller at ``controller_id``: model, firmware version, board, state; None
    when nothing answers PING there (the port is a servo bus, or no controller runs)."""
    # echo "auto": on a one-wire servo bus the PING's own echo must not pass for a reply
    with ControllerClient.open(port, baud, controller_id, retries=1, echo="auto") as ctl:
        try:
            ctl.link.ping(ctl.id)
        except (DxlTimeout, CorruptPacket, ServoError):
            return None
        table = ctl.table
        try:
            with ctl.link_errors("the doctor's reads"):
                found = ctl.read("Model Number", "Firmware Version", "State", "Error Flags")
                if found["Model Number"] == table.model_number:  # a page only ours has
                    found |= ctl.read("Board")
        except SnakebotError as exc:
            fail = Check("controller", "fail", str(exc), "check the cable and the baud rate")
            return ControllerFound([fail])
    checks = [Check("controller", "ok", f"answers PING at ID {controller_id}, {baud} baud")]
    if found["Model Number"] != table.model_number:
        checks.append(
            Check(
                "controller model",
                "fail",
                f"model number {found['Model Number']}, not a snakebot controller "
                f"({table.model_number})",
                "flash the snakebot firmware: snakebot flash --port ...",
            )
        )
        return ControllerFound(checks)
    checks.append(Check("controller model", "ok", f"snakebot controller ({table.model_number})"))
    version = found["Firmware Version"]
    if version != table.firmware_version:
        checks.append(
            Check(
                "controller firmware",
                "fail",
                f"firmware version {version}, this snakebot speaks {table.firmware_version}",
                "flash the firmware built from this snakebot (make firmware, snakebot flash), "
                "or install the snakebot that matches it",
            )
        )
    else:
        checks.append(Check("controller firmware", "ok", f"version {version}"))
    named = {v: k for k, v in table.enums["Board"].items()}.get(found["Board"])
    checks.append(board(port, named or f"value {found['Board']}", expected_board))
    states = {v: k for k, v in table.enums["State"].items()}
    state = states.get(found["State"], str(found["State"]))
    if state == "SAFE":
        checks.append(
            Check(
                "controller state",
                "warn",
                f"SAFE (Error Flags 0x{found['Error Flags']:04X})",
                "snakebot monitor shows why; snakebot stop, then fix the cause (servo alarm, "
                "bus loss, link timeout)",
            )
        )
    else:
        checks.append(Check("controller state", "ok", state))
    return ControllerFound(checks, None if named in (None, NO_BOARD) else named.lower())


def board(port: str, named: str, expected: str = ANY_BOARD, sysfs: Path = TTY_SYSFS) -> Check:
    """The board the controller named (a Board enum name), against ``expected`` (a
    :func:`board_names` entry or :data:`ANY_BOARD`) and against the port: on a hardware
    adapter anything but the CM-530's image is not what a robot runs."""
    name = "controller board"
    shown = named.lower()
    hardware = HARDWARE_BOARD.lower()
    flash = f"flash the {hardware} image `make firmware` builds: snakebot flash --port {port}"
    detail = shown
    if named == NO_BOARD:
        detail = "none named (the controller's logic run on the host, or older firmware)"
    if expected not in (ANY_BOARD, shown):
        fix = flash if expected == hardware else f"use the port of a {expected} controller"
        return Check(name, "fail", f"{detail}, not the {expected} expected", fix)
    if shown != hardware and on_hardware(port, sysfs):
        device = Path(os.path.realpath(port)).name
        return Check(name, "warn", f"{detail}, answering on {device}, a hardware port", flash)
    return Check(name, "ok", detail)


def servo_bus(port: str, ids: Iterable[int], bauds: Sequence[int]) -> list[Check]:
    """Scan ``ids`` at each of ``bauds``; then each servo found, against its own limits."""
    ids = list(ids)
    with open_port(port, bauds[0]) as link:
        tap = _Tap(link)
        probes = []
        for p in bus_scan.scan_probes(tap, ids, bauds):  # type: ignore[arg-type]
            heard, sent = tap.take()
            # Colliding replies can merge into bytes that never make a packet: the client
            # then reports silence, but more came back than the echo of what was sent.
            probes.append((p, p.garbled or (p.info is None and heard > sent)))
        found = [p.info for p, _ in probes if p.info is not None]
        checks = [_bauds_found(found, bauds)]
        for p, damaged in probes:
            if damaged:
                checks.append(
                    Check(
                        f"servo {p.id}",
                        "fail",
                        f"at {p.baud} bit/s every reply arrived damaged: two servos share ID "
                        f"{p.id}, or the line is noisy",
                        "connect the servos one at a time and give each its own ID "
                        "(snakebot bus set-id); check the cables",
                    )
                )
        for info in found:
            checks += _servo(DxlClient(link, info.baud), info)
    return checks


class _Tap:
    """A serial port that counts the bytes read from it and written to it."""

    def __init__(self, port: serial.SerialBase) -> None:
        object.__setattr__(self, "_port", port)
        object.__setattr__(self, "_heard", 0)
        object.__setattr__(self, "_sent", 0)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._port, name)

    def __setattr__(self, name: str, value: Any) -> None:
        setattr(self._port, name, value)

    def read(self, size: int = 1) -> bytes:
        data = self._port.read(size)
        object.__setattr__(self, "_heard", self._heard + len(data))
        return data

    def write(self, data: bytes) -> int | None:
        object.__setattr__(self, "_sent", self._sent + len(data))
        return self._port.write(data)

    def take(self) -> tuple[int, int]:
        """Bytes heard and sent since the last call."""
        counts = (self._heard, self._sent)
        object.__setattr__(self, "_heard", 0)
        object.__setattr__(self, "_sent", 0)
        return counts


def _bauds_found(found: list[bus_scan.ServoInfo], bauds: Sequence[int]) -> Check:
    if not found:
        return Check(
            "servo bus",
            "fail",
            f"no servo answered at {', '.join(map(str, bauds))} bit/s",
            "check the servos' power and the cable; try every rate (all bauds)",
        )
    rates = sorted({s.baud for s in found}, reverse=True)
    detail = f"{len(found)} servo(s) at {', '.join(map(str, rates))} bit/s"
    if len(rates) > 1:
        return Check(
            "servo bus",
            "warn",
            detail + ": not all at one rate",
            "give every servo the same rate: snakebot bus set-baud",
        )
    return Check("servo bus", "ok", detail)


def _servo(client: DxlClient, info: bus_scan.ServoInfo) -> list[Check]:
    name = f"servo {info.id}"
    ident = Check(name, "ok", f"{info.label}, firmware {info.firmware}")
    if info.model is None:
        return [Check(name, "warn", f"{info.label}: snakebot has no description of it", "")]
    table = ControlTable.for_model_number(info.model_number)
    entries = sorted((table.by_name(n) for n in SERVO_REGISTERS), key=lambda e: e.address)
    start, end = entries[0].address, max(e.address + e.size for e in entries)
    # Read past the error bits: a servo in alarm (low voltage, too hot) still reports its
    # registers, and they say why.
    reply = client.transact(read(info.id, start, end - start), info.id, end - start, check=False)
    v = {
        e.name: register_values.decode(
            e,
            int.from_bytes(reply.params[e.address - start : e.address + e.size - start], "little"),
            table,
        )
        for e in entries
    }
    alarm = (
        [Check(f"{name} alarm", "fail", f"reports {info.error.describe()}", "see the checks below")]
        if info.error
        else []
    )
    return [
        ident,
        *alarm,
        _return_delay(name, info.id, v["Return Delay Time"]),
        _voltage(name, v["Present Voltage"], v["Min Voltage Limit"], v["Max Voltage Limit"]),
        _temperature(name, v["Present Temperature"], v["Temperature Limit"]),
        _torque(name, info.id, v["Torque Limit"], v["Max Torque"]),
    ]


def _physical(d: dict) -> float:
    return float(d.get("physical", d["value"]))


def _return_delay(name: str, servo_id: int, delay: dict) -> Check:
    assumed = settings.resolve_return_delay_us()
    us = _physical(delay)
    if us <= assumed:
        return Check(f"{name} return delay", "ok", f"{us:g} us")
    return Check(
        f"{name} return delay",
        "warn",
        f"{us:g} us, longer than the {assumed:g} us snakebot waits for",
        f"SNAKEBOT_RETURN_DELAY_US={us:g}, or shorten it: snakebot bus write {servo_id} "
        f"return-delay-time {assumed:g}us",
    )


def _voltage(name: str, now: dict, low: dict, high: dict) -> Check:
    volts, lo, hi = _physical(now), _physical(low), _physical(high)
    if lo <= volts <= hi:
        return Check(f"{name} voltage", "ok", f"{volts:g} V (limits {lo:g}-{hi:g} V)")
    return Check(
        f"{name} voltage",
        "fail",
        f"{volts:g} V, outside its limits {lo:g}-{hi:g} V",
        "charge or replace the battery, or check the supply and the cable",
    )


def _temperature(name: str, now: dict, limit: dict) -> Check:
    deg, top = _physical(now), _physical(limit)
    detail = f"{deg:g} C (limit {top:g} C)"
    if deg >= top:
        return Check(f"{name} temperature", "fail", detail, "let it cool; lighten its load")
    if deg >= top - TEMPERATURE_MARGIN:
        return Check(f"{name} temperature", "warn", detail, "let it cool before a long run")
    return Check(f"{name} temperature", "ok", detail)


def _torque(name: str, servo_id: int, limit: dict, most: dict) -> Check:
    raw, top = int(limit["value"]), int(most["value"])
    detail = f"Torque Limit {raw} of Max Torque {top}"
    if raw == 0:
        return Check(
            f"{name} torque limit",
            "fail",
            detail + ": an alarm shut it down",
            f"clear the cause, then snakebot bus write {servo_id} torque-limit {top}",
        )
    if raw < top:
        return Check(
            f"{name} torque limit",
            "warn",
            detail,
            f"snakebot bus write {servo_id} torque-limit {top} for full torque",
        )
    return Check(f"{name} torque limit", "ok", detail)


def bootloader(port: str, timeouts: FlashTimeouts) -> Check:
    """Catch the bootloader after a reset the user makes, then start the application."""
    try:
        with open_port(port, PC_LINK_BAUD, timeout=0) as link:
            banner = enter_bootloader(link, timeouts)
            start_application(link, timeouts)
    except SnakebotError as exc:
        return Check("bootloader", "fail", str(exc), f"{RESET_HINT} while doctor waits")
    return Check("bootloader", "ok", f"answered: {first_line(banner)}; sent GO")
