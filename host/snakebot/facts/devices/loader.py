"""Reading the device descriptions shipped in ``snakebot/facts/devices/data/*.json``.

One file per device, in one schema (protocol/README.md, "Device descriptions"). A
variant names the device it is ``based_on`` and gives only what differs: its model
number, description, ``defaults`` by register name, extra ``scales`` and registers to
``add``. Files are read with
:mod:`importlib.resources`, so an installed wheel works the same as a checkout.
"""

from __future__ import annotations

import json
from dataclasses import replace
from functools import cache
from importlib import resources
from typing import Any

from snakebot.facts.devices.device import Baud, Device, Page, Position, ServoWindow
from snakebot.facts.devices.errors import DeviceError
from snakebot.facts.devices.register import Register
from snakebot.facts.devices.units import Encoding, Scale, exact, shown

SCHEMA = 1
_REGISTER_KEYS = {
    "address", "offset", "size", "name", "access", "default", "min", "max", "area", "scale",
    "encoding", "description", "emulator_default", "enum", "mirrors", "ticks", "read",
}  # fmt: skip


@cache
def _documents() -> dict[str, tuple[str, dict[str, Any]]]:
    """Every description file: device name -> (file name, parsed JSON)."""
    docs: dict[str, tuple[str, dict[str, Any]]] = {}
    folder = resources.files("snakebot.facts.devices").joinpath("data")
    for entry in sorted(folder.iterdir(), key=lambda e: e.name):
        if not entry.name.endswith(".json"):
            continue
        try:
            doc = json.loads(entry.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise DeviceError(f"cannot read device file {entry.name}: {exc}; restore it") from exc
        if doc.get("schema") != SCHEMA:
            raise DeviceError(f"{entry.name}: schema {doc.get('schema')!r}, expected {SCHEMA}")
        docs[doc["name"]] = (entry.name, doc)
    return docs


def names(kind: str | None = None) -> tuple[str, ...]:
    """The devices described (of ``kind`` "servo" or "controller" if given), by name."""
    return tuple(n for n in sorted(_documents()) if kind is None or load(n).kind == kind)


def source(name: str) -> str:
    """The file name of device ``name``'s description (in ``snakebot/facts/devices/data``)."""
    return _documents()[load(name).name][0]


def load(name: str) -> Device:
    """The device called ``name`` (case-insensitive): "AX-12A", "controller", ..."""
    for known in _documents():
        if known.lower() == name.strip().lower():
            return _build(known)
    raise DeviceError(
        f"unknown device {name!r}: known devices are {', '.join(sorted(_documents()))}"
    )


def by_model_number(number: int, kind: str = "servo") -> Device:
    """The device of ``kind`` whose Model Number is ``number``."""
    for name in names(kind):
        device = load(name)
        if device.model_number == number:
            return device
    known = ", ".join(f"{load(n).model_number} ({n})" for n in names(kind))
    raise DeviceError(f"unknown model number {number}: known are {known}")


def _merged(name: str) -> dict[str, Any]:
    """The document of ``name`` with its base's facts filled in."""
    file, doc = _documents()[name]
    base_name = doc.get("based_on")
    if base_name is None:
        return dict(doc)
    if base_name not in _documents():
        raise DeviceError(f"{file}: based_on {base_name!r} is not a described device")
    merged = _merged(base_name)
    merged.update({k: v for k, v in doc.items() if k not in ("defaults", "scales", "add")})
    merged["scales"] = {**merged.get("scales", {}), **doc.get("scales", {})}
    registers = [dict(r) for r in merged["registers"]] + list(doc.get("add", []))
    overrides = {k.lower(): v for k, v in doc.get("defaults", {}).items()}
    for reg in registers:
        if reg["name"].lower() in overrides:
            reg["default"] = overrides.pop(reg["name"].lower())
    if overrides:
        raise DeviceError(f"{file}: defaults for unknown registers {sorted(overrides)}")
    merged["registers"] = registers
    return merged


def _scale(file: str, spec: object, scales: dict[str, Scale]) -> Scale | None:
    """A register's scale: none, a name from ``scales``, or one written inline."""
    if spec is None:
        return None
    if isinstance(spec, str):
        if spec not in scales:
            raise DeviceError(f'{file}: unknown scale {spec!r}: define it under "scales"')
        return scales[spec]
    return _inline_scale(file, spec)


def _inline_scale(file: str, spec: object) -> Scale:
    if isinstance(spec, dict) and set(spec) == {"unit", "factor"}:
        return Scale(str(spec["unit"]), exact(spec["factor"]), shown(spec["factor"]))
    raise DeviceError(f'{file}: a scale is a name or {{"unit", "factor"}}, not {spec!r}')


def _register(
    file: str, raw: dict[str, Any], scales: dict[str, Scale], servo: Device | None
) -> Register:
    unknown = set(raw) - _REGISTER_KEYS
    if unknown:
        raise DeviceError(f"{file}: unknown key(s) {sorted(unknown)} in register {raw.get('name')}")
    scale = _scale(file, raw.get("scale"), scales)
    try:
        encoding = Encoding(raw.get("encoding", "unsigned"))
    except ValueError:
        known = ", ".join(e.value for e in Encoding)
        raise DeviceError(
            f"{file}: {raw['name']}: encoding {raw['encoding']!r} is not one of {known}"
        ) from None
    low, high, default = raw.get("min"), raw.get("max"), raw.get("default")
    if ("mirrors" in raw or "ticks" in raw) and servo is None:
        raise DeviceError(f"{file}: {raw['name']} refers to a servo, but no servo_model is set")
    if "mirrors" in raw:  # a servo-window field: unit and encoding are the servo's
        mirrored = servo.register(raw["mirrors"])
        scale, encoding = mirrored.scale, mirrored.encoding
    if "ticks" in raw:  # a servo position tick: the servo's range, its centre or an end
        position = servo.require_position()
        (low, high), scale = position.range, position.scale
        ends = {"centre": position.centre, "min": low, "max": high}
        if raw["ticks"] not in ends:
            raise DeviceError(f"{file}: {raw['name']}: ticks is one of {', '.join(ends)}")
        default = ends[raw["ticks"]]
    return Register(
        address=raw["address"] if "address" in raw else raw["offset"],
        size=raw["size"],
        name=raw["name"],
        access=raw["access"],
        default=default,
        min=low,
        max=high,
        area=raw.get("area"),
        scale=scale,
        encoding=encoding,
        description=raw.get("description", ""),
        emulator_default=raw.get("emulator_default"),
        enum=raw.get("enum"),
    )


def _read_ranges(
    file: str, raws: list[dict[str, Any]], registers: list[Register]
) -> list[Register]:
    """The registers with their ``read`` ranges: ``[low, high]``, or the name of a
    register whose write range values read also lie in (Present Position: Goal
    Position's), so that a range is written once."""
    by_name = {r.name: r for r in registers}
    out = []
    for raw, reg in zip(raws, registers, strict=True):
        spec = raw.get("read")
        if spec is None:
            out.append(reg)
            continue
        if isinstance(spec, str) and spec in by_name and by_name[spec].min is not None:
            low, high = by_name[spec].min, by_name[spec].max
        elif isinstance(spec, list) and len(spec) == 2 and all(type(v) is int for v in spec):
            low, high = spec
        else:
            raise DeviceError(
                f"{file}: {reg.name}: read is [low, high] or the name of a register with a "
                f"write range, not {spec!r}"
            )
        full_low, full_high = replace(reg, min=None, max=None).value_range()
        if not full_low <= low <= high <= full_high:
            raise DeviceError(
                f"{file}: {reg.name}: read range {low}..{high} does not fit the field "
                f"({full_low}..{full_high})"
            )
        out.append(replace(reg, read_min=low, read_max=high))
    return out


def _check(file: str, device: Device) -> None:
    """Refuse overlapping, oversized or misfiled registers and dangling references."""
    end = 0
    for reg in sorted(device.registers, key=lambda r: r.address):
        problem = None
        if reg.address < end:
            problem = "overlaps the register before it"
        elif reg.size < 1 or reg.end > device.table_size:
            problem = "does not fit the table"
        elif reg.access not in ("R", "W", "RW"):
            problem = "has access other than R, W, RW"
        elif device.eeprom_end is not None and reg.area != (
            "EEPROM" if reg.address < device.eeprom_end else "RAM"
        ):
            problem = "is in the wrong area"
        elif not reg.writable and (reg.min is not None or reg.max is not None):
            problem = "is read-only but has a write range"
        elif reg.size <= 4 and reg.access == "RW" and reg.default is not None:
            if not reg.accepts(reg.default):
                problem = f"has default {reg.default} outside its range"
        if problem:
            raise DeviceError(
                f"{file}: {device.name} register {reg.name!r} {problem}: fix the file"
            )
        end = reg.end


def _page(
    file: str,
    raw: dict[str, Any],
    scales: dict[str, Scale],
    servo: Device | None,
    window: dict[str, Any] | None,
) -> Page:
    """One described page of the window (``pages`` in the controller's file)."""
    if window is None:
        raise DeviceError(f'{file}: "pages" need a "servo_window" to show them: add one')
    return Page(
        number=raw["page"],
        name=raw["name"],
        description=raw.get("description", ""),
        base=window["address"],
        fields=tuple(_register(file, f, scales, servo) for f in raw["fields"]),
    )


def _check_pages(file: str, device: Device) -> None:
    """Refuse pages that clash with the servo records, with each other or with the
    registers' names, and fields that overlap or leave the window."""
    window = device.servo_window
    if not device.pages or window is None:
        return
    size = window.records * window.record_size
    selector = device.register("Window Page")
    low, high = selector.value_range()
    servo_pages = -(-device.limits["max_joints"] // window.records)
    names = {r.name.lower() for r in device.registers}
    numbers: set[int] = set()
    for page in device.pages:
        where = f"{file}: window page {page.number} ({page.name})"
        if not servo_pages <= page.number <= high or page.number < low:
            raise DeviceError(f"{where}: numbers run {servo_pages}..{high}: renumber it")
        if page.number in numbers:
            raise DeviceError(f"{where}: the number is taken twice: renumber one")
        numbers.add(page.number)
        end = 0
        for f in sorted(page.fields, key=lambda r: r.address):
            # a field longer than a number is a byte string: no unit, no value names
            text = f.size > 4 and f.scale is None and f.enum is None
            if f.address < end or f.end > size or (f.size > 4 and not text):
                raise DeviceError(
                    f"{where}: field {f.name!r} overlaps, leaves the window or passes 4 bytes"
                    " without being a byte string (no scale, no enum)"
                )
            if f.name.lower() in names:
                raise DeviceError(f"{where}: field {f.name!r} is also a register's name")
            names.add(f.name.lower())
            end = f.end


@cache
def _build(name: str) -> Device:
    """The device called exactly ``name``, built once."""
    file, _ = _documents()[name]
    doc = _merged(name)
    try:
        servo = _build(doc["servo_model"]) if doc.get("servo_model") else None
        scales = {k: _inline_scale(file, v) for k, v in doc.get("scales", {}).items()}
        if servo is not None:  # the controller speaks in its servos' units
            scales = {**servo.scales, **scales}
        registers = [_register(file, r, scales, servo) for r in doc["registers"]]
        registers = _read_ranges(file, doc["registers"], registers)
        # the model number is written once, as a device fact
        registers = [
            r if r.name != "Model Number" else replace(r, default=doc["model_number"])
            for r in registers
        ]
        by_name = {r.name: r for r in registers}
        baud = doc.get("baud")
        position = doc.get("position")
        window = doc.get("servo_window")
        device = Device(
            name=doc["name"],
            kind=doc["kind"],
            protocol=doc["protocol"],
            model_number=doc["model_number"],
            description=doc.get("description", ""),
            table_size=doc["table_size"],
            registers=tuple(sorted(registers, key=lambda r: r.address)),
            scales=scales,
            eeprom_end=doc.get("eeprom_end"),
            status_return_level=doc.get("status_return_level"),
            baud=None
            if baud is None
            else Baud(
                by_name[baud["register"]],
                baud["clock_hz"],
                {int(k): v for k, v in baud.get("fixed", {}).items()},
                baud["tolerance"],
            ),
            position=None
            if position is None
            else Position(by_name[position["register"]], position["centre"]),
            based_on=_documents()[name][1].get("based_on"),
            servo_model=doc.get("servo_model"),
            limits=dict(doc.get("limits", {})),
            max_speed_rpm=doc.get("max_speed_rpm"),
            servo_window=None
            if window is None
            else ServoWindow(
                window["address"],
                window["record_size"],
                window["records"],
                tuple(_register(file, f, scales, servo) for f in window["fields"]),
            ),
            pages=tuple(_page(file, p, scales, servo, window) for p in doc.get("pages", [])),
            enums={k: dict(v["values"]) for k, v in doc.get("enums", {}).items()},
            flags=tuple(k for k, v in doc.get("enums", {}).items() if v["kind"] == "flags"),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise DeviceError(f"{file}: missing or malformed {exc}: fix the file") from exc
    if device.status_return_level is not None:
        device.register(device.status_return_level)
    goal = device.position
    if goal is not None:
        low, high = goal.register.value_range()
        if goal.register.scale is None or not low <= goal.centre <= high:
            raise DeviceError(
                f"{file}: the position needs a register with a scale and a centre in its range"
            )
    _check(file, device)
    _check_pages(file, device)
    return device
