"""The controller's settings by name: which registers they are, reading a value given
with a unit or a value name, and showing one in its unit, all from the controller's
description (``snakebot.facts.devices``), so no register, range or unit is written here."""

from __future__ import annotations

import difflib
import re
from typing import Any

from snakebot.errors import InputError, SnakebotError, quoted
from snakebot.facts.controller import Controller
from snakebot.facts.devices import Register
from snakebot.formats.protocol import ErrorFlags
from snakebot.formats.register_values import check_write, decode, describe_value, parse_value
from snakebot.link.controller.client import ControllerClient


class ConfigError(InputError):
    """A setting name or value the controller's description does not allow (exit 2)."""


def _squash(text: str) -> str:
    return re.sub(r"[\s_\-]+", "", text).lower()


def _cli_name(reg: Register) -> str:
    return reg.name.lower().replace(" ", "-")


def settings(table: Controller) -> list[Register]:
    """The registers that are settings: readable and writable, except those the upload
    protocol uses and the window page selectors, which are machinery, not settings."""
    return [
        r
        for r in table.registers
        if r.access == "RW" and not r.name.startswith("Upload") and not r.name.endswith("Page")
    ]


def find_setting(table: Controller, name: str) -> Register:
    """The setting called ``name`` (any case; spaces, '-' or '_' alike), or
    :class:`ConfigError` naming the closest ones."""
    by_name = {_squash(r.name): r for r in settings(table)}
    found = by_name.get(_squash(name))
    if found is not None:
        return found
    close = difflib.get_close_matches(_squash(name), list(by_name), n=3, cutoff=0.5)
    hint = (
        "did you mean " + " or ".join(_cli_name(by_name[c]) for c in close) + "?"
        if close
        else "`snakebot config` lists them"
    )
    raise ConfigError(f"the controller has no setting {quoted(name)}: {hint}")


def parse_setting(table: Controller, reg: Register, text: str) -> int:
    """The raw value ``text`` asks for: a value name of the register's set (HOLD), a
    whole number, or an amount with a unit (1.5s, 10deg); range-checked."""
    names = table.enums.get(reg.enum, {}) if reg.enum else {}
    by_name = {_squash(k): v for k, v in names.items()}
    if _squash(text) in by_name:
        return by_name[_squash(text)]
    try:
        raw = parse_value(reg, text)
        check_write(reg, raw)
    except SnakebotError as exc:
        named = f"; or one of {', '.join(names)}" if names else ""
        raise ConfigError(f"{exc}{named}") from None
    return raw


def shown(table: Controller, reg: Register, raw: int) -> dict[str, Any]:
    """One setting's value as JSON: name, raw value, and its unit and physical value or
    its value name, with the same text the human output prints."""
    out = decode(reg, raw)
    names = {v: k for k, v in table.enums.get(reg.enum, {}).items()} if reg.enum else {}
    if raw in names:
        out["meaning"] = names[raw]
    elif reg.name.endswith("Error Mask"):  # a mask of the status packet's error bits
        out["meaning"] = ErrorFlags(raw).describe()
    low, high = reg.min, reg.max
    out["range"] = None if low is None or high is None else [low, high]
    out["text"] = describe_value(out)
    out["description"] = reg.description
    return out


def configure(
    ctl: ControllerClient, name: str | None = None, value: str | None = None
) -> list[dict[str, Any]]:
    """Every setting of the controller (``name`` None), or the setting ``name``, after
    writing ``value`` to it when one is given (parsed in the setting's units and checked
    against its range before anything is sent), as read back: one :func:`shown` row each.
    An ID written becomes the client's, since the controller answers at it from then on."""
    table = ctl.table
    regs = settings(table) if name is None else [find_setting(table, name)]
    if value is not None:
        raw = parse_setting(table, regs[0], value)
        ctl.identify()
        with ctl.link_errors(f"the write of {regs[0].name}"):
            ctl.write({regs[0].name: raw})
        if regs[0].name == "ID":
            ctl.id = raw
    with ctl.link_errors("the read of its settings"):
        values = ctl.read(*(r.name for r in regs))
    return [shown(table, r, values[r.name]) for r in regs]
