"""The one table of snakebot's ``SNAKEBOT_*`` environment variables, and the one resolver
that reads, parses and checks any of them.

Every variable has one row in :data:`SETTINGS`: its name, kind, unit, allowed range,
default and a one-line meaning. :func:`resolve` reads a variable (an empty one counts as
unset), parses it by its kind and checks it against its range; a value it cannot use
raises :class:`SettingError` with one line naming the variable, the value, what is
allowed and the fix (the CLI reports it with exit 2). :func:`check_environment` resolves
every variable that is set, so that the CLI refuses a bad one before any work starts,
including a variable the command at hand never reads (``SNAKEBOT_PROTOCOL_DIR``, read
only by the tests and generators, would otherwise be accepted silently).
``docs/settings.md`` is checked against this table by ``tests/docs/test_docs.py``.

Why here, at the package root and not in ``snakebot.link``: the variables are read in
every layer: ``snakebot.paths`` (root), ``snakebot.link`` (transport, upload, flash,
library backups), ``snakebot.sim.qemu`` and ``snakebot.cli.errors``. The root is the one
place all of them may import (root imports nothing of the layers, ``link`` never imports
``sim``), so the table and the resolver live here; the link-specific groups that keep a
keyword argument ahead of the environment (``snakebot.link.transport.settings``,
``snakebot.link.controller.settings``, ``snakebot.link.flash.settings``) are built on
:func:`resolve` and take their defaults from this table. A default that is a fact of a
higher layer (the controller's ID, from its control table) is named in the row's
``default_note`` and computed by its reader. Standard library only: the CLI imports this
module at start-up.
"""

from __future__ import annotations

import math
import os
import shutil
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from snakebot.errors import InputError, quoted

Kind = Literal["int", "float", "choice", "flag", "text", "dir", "out_dir", "program"]
"""How a value is parsed and checked:

* ``int``, ``float``: a number within ``[low, high]`` (``int`` also takes ``2.0``);
* ``choice``: one of the words of ``choices`` (any case);
* ``flag``: on when set to anything;
* ``text``: any text (a port name, read by click's ``envvar``);
* ``dir``: an existing directory;
* ``out_dir``: a directory, or a path where one can be made (nothing else is there);
* ``program``: an executable file, or a name found on ``PATH``.
"""

Value = int | float | bool | str | Path


class SettingError(InputError, ValueError):
    """An environment variable has a value snakebot cannot use (bad input, exit 2)."""


@dataclass(frozen=True)
class Setting:
    """One environment variable: one row of the table."""

    name: str
    kind: Kind
    meaning: str
    default: int | float | str | None = None
    """The value when the variable is unset, in ``unit``; None: computed by the reader
    (see ``default_note``) or nothing."""
    unit: str = ""
    low: float | None = None
    high: float | None = None
    choices: Mapping[str, Value] = field(default_factory=dict)
    default_note: str = ""
    """Qualifies the default, or says what it is when the table cannot hold it."""
    example: str = ""
    """The fix for a bad value, when the default is not a good example."""
    group: str = ""
    """The section of docs/settings.md (and which readers): ports, transport, upload,
    flash, places, debug, tests."""

    def range_text(self) -> str:
        """The allowed values as docs/settings.md writes them."""
        if self.kind in ("int", "float"):
            return f"{_num(self.low)}-{_num(self.high)}"
        if self.kind == "choice":
            return ", ".join(f"`{word}`" for word in self.choices)
        return {
            "flag": "any non-empty value",
            "text": "",
            "dir": "an existing directory",
            "out_dir": "a directory, or a path where one can be made",
            "program": "an executable file, or a name on `PATH`",
        }[self.kind]

    def allowed(self) -> str:
        """The allowed values in a sentence, for error messages."""
        unit = f" of {_UNIT_WORDS.get(self.unit, self.unit)}" if self.unit else ""
        if self.kind == "int":
            return f"a whole number{unit} from {_num(self.low)} to {_num(self.high)}"
        if self.kind == "float":
            return f"a number{unit} from {_num(self.low)} to {_num(self.high)}"
        if self.kind == "choice":
            return "one of " + ", ".join(self.choices)
        return self.range_text().replace("`", "")

    def default_text(self) -> str:
        """The default as docs/settings.md writes it."""
        if self.default is None:
            shown = ""
        elif isinstance(self.default, str):
            shown = f"`{self.default}`"
        else:
            shown = _num(self.default)
        if shown and self.default_note:
            return f"{shown} ({self.default_note})"
        return shown or self.default_note

    def fix(self) -> str:
        if self.example:
            return self.example
        if self.default is not None:
            return f"set it to e.g. {self.default} or unset it for the default"
        return "unset it"

    def error(self, text: str, why: str = "") -> SettingError:
        """The one-line error for ``text``, a value of this variable."""
        because = f" ({why})" if why else ""
        return SettingError(
            f"{self.name}={quoted(text)} is not {self.allowed()}{because}; {self.fix()}"
        )

    def parse(self, text: str) -> Value:
        """``text`` (stripped, not empty) as a value of this kind, or :class:`SettingError`."""
        if self.kind in ("int", "float"):
            return self._number(text)
        if self.kind == "choice":
            try:
                return self.choices[text.lower()]
            except KeyError:
                raise self.error(text) from None
        if self.kind == "flag":
            return True
        if self.kind == "text":
            return text
        if self.kind == "program":
            found = shutil.which(text)
            if found is None:
                raise self.error(text)
            return found
        path = Path(text).expanduser()
        if self.kind == "dir" and not path.is_dir():
            raise self.error(text)
        if self.kind == "out_dir" and path.exists() and not path.is_dir():
            raise self.error(text, "something else is there")
        return path

    def _number(self, text: str) -> int | float:
        assert self.low is not None and self.high is not None
        try:
            number = float(text)
        except ValueError:
            raise self.error(text) from None
        if not self.low <= number <= self.high:  # also refuses nan and inf
            raise self.error(text)
        if self.kind == "float":
            return number
        if not number.is_integer():
            raise self.error(text)
        return int(number)


_UNIT_WORDS = {"s": "seconds", "us": "microseconds"}


def _num(x: float | None) -> str:
    """A number as the table writes it: 16, 0.05, 4294967295."""
    assert x is not None
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


_ECHO_WORDS: dict[str, Value] = {
    "auto": "auto",
    "on": True,
    "off": False,
    "1": True,
    "0": False,
    "true": True,
    "false": False,
    "yes": True,
    "no": False,
}

_TABLE = (
    # -- ports and IDs (read by click's ``envvar``) --
    Setting(
        "SNAKEBOT_BUS_PORT",
        "text",
        "the Dynamixel bus adapter for `snakebot bus ...`",
        default_note="none (a port must be given)",
        group="ports",
    ),
    Setting(
        "SNAKEBOT_PORT",
        "text",
        "the CM-530's PC link for the controller commands and `snakebot flash`",
        default_note="none (a port must be given)",
        group="ports",
    ),
    Setting(
        "SNAKEBOT_CONTROLLER_ID",
        "int",
        "the controller's Protocol 1.0 ID on the PC link",
        low=0,
        high=253,
        default_note="the `ID` register's default in "
        "`host/snakebot/facts/devices/data/controller.json`",
        example="set it to the controller's ID or unset it for the default",
        group="ports",
    ),
    # -- transport: every Protocol 1.0 transaction (snakebot.link.transport.settings) --
    Setting(
        "SNAKEBOT_RETRIES",
        "int",
        "extra tries after a timed-out or corrupt reply",
        default=2,
        unit="attempts",
        low=0,
        high=100,
        group="transport",
    ),
    Setting(
        "SNAKEBOT_LATENCY_MS",
        "float",
        "how long a USB-serial adapter may hold received bytes",
        default=16,
        unit="ms",
        low=0,
        high=10_000,
        default_note="the adapter's latency timer where it shows one (FTDI on Linux); 0 for "
        "a pseudo-terminal or sim://",
        group="transport",
    ),
    Setting(
        "SNAKEBOT_MARGIN_MS",
        "float",
        "allowance for the host scheduling the program late",
        default=4,
        unit="ms",
        low=0,
        high=10_000,
        default_note="500 on a pseudo-terminal; 0.1 for a scan's silent IDs",
        group="transport",
    ),
    Setting(
        "SNAKEBOT_RETURN_DELAY_US",
        "float",
        "the servos' Return Delay Time",
        default=500,
        unit="us",
        low=0,
        high=10_000,
        group="transport",
    ),
    Setting(
        "SNAKEBOT_ECHO",
        "choice",
        "whether the bus echoes each instruction before the reply",
        default="auto",
        choices=_ECHO_WORDS,
        group="transport",
    ),
    Setting(
        "SNAKEBOT_ECHO_PROBE_MS",
        "float",
        "the shortest wait for the echo of the `auto` mode's probe",
        default=250,
        unit="ms",
        low=0,
        high=10_000,
        group="transport",
    ),
    # -- uploading a gait table (snakebot.link.controller.settings) --
    Setting(
        "SNAKEBOT_UPLOAD_RETRIES",
        "int",
        "whole-table resends after a lost or damaged chunk",
        default=3,
        unit="attempts",
        low=0,
        high=50,
        group="upload",
    ),
    Setting(
        "SNAKEBOT_UPLOAD_WINDOW",
        "int",
        "packets in flight before the first must be answered",
        default=8,
        unit="packets",
        low=1,
        high=64,
        group="upload",
    ),
    # -- flashing the firmware (snakebot.link.flash.settings) --
    *(
        Setting(
            f"SNAKEBOT_FLASH_{name}",
            "float",
            meaning,
            default=default,
            unit="s",
            low=0,
            high=3600,
            group="flash",
        )
        for name, default, meaning in (
            ("RESET_TIMEOUT_S", 20, "how long `#` is sent while the CM-530 is reset"),
            ("HASH_INTERVAL_S", 0.001, "pause between two `#` characters"),
            ("QUIET_S", 0.2, "silence that marks the end of the bootloader's banner"),
            ("QUIET_TIMEOUT_S", 3, "longest the bootloader may talk after it answered `#`"),
            ("READY_TIMEOUT_S", 3, "wait for `Ready..` after the load command"),
            ("READY_SETTLE_S", 0.05, "pause after `Ready..` before the first image byte"),
            ("CHECKSUM_TIMEOUT_S", 3, "base wait for the `Checksum:` report"),
            ("PAGE_TIME_S", 0.05, "added to that wait per 2 KB flash page of the image"),
            ("GO_TIMEOUT_S", 0.5, "how long to listen for an answer to `GO`"),
            ("BOOT_TIMEOUT_S", 10, "how long the new firmware may take to answer PING"),
        )
    ),
    # -- where things are --
    Setting(
        "SNAKEBOT_PROTOCOL_DIR",
        "dir",
        "where the control tables, test vectors and layouts are read from",
        default_note="`protocol/` of the repository snakebot was installed from",
        example="set it to the protocol/ folder of a snakebot checkout or unset it",
        group="places",
    ),
    Setting(
        "SNAKEBOT_QEMU",
        "program",
        "the QEMU executable that runs the firmware image",
        default_note="`qemu-system-arm` on `PATH`",
        example="set it to the path of qemu-system-arm or unset it",
        group="places",
    ),
    Setting(
        "SNAKEBOT_LIBRARY_BACKUP_DIR",
        "out_dir",
        "where `snakebot flash` saves the controller's gait library",
        default_note="`library-backups` in snakebot's application directory "
        "(`~/.config/snakebot` on Linux)",
        example="set it to a directory (it is made if missing) or unset it",
        group="places",
    ),
    # -- debugging --
    Setting(
        "SNAKEBOT_DEBUG",
        "flag",
        "a bug in snakebot shows its Python traceback",
        default_note="unset",
        group="debug",
    ),
    Setting(
        "SNAKEBOT_MCU_STRICT",
        "flag",
        "the emulated CM-530 stops at the first access to a register it does not model",
        default_note="unset",
        group="debug",
    ),
    # -- read by the test suite only --
    Setting(
        "SNAKEBOT_RELIABILITY_EXAMPLES",
        "int",
        "hypothesis examples of the transport-under-faults test",
        default=25,
        unit="examples",
        low=1,
        high=100_000,
        group="tests",
    ),
    Setting(
        "SNAKEBOT_CAMPAIGN_SEED",
        "int",
        "the seed of the fault campaigns",
        default=1,
        low=0,
        high=2**32 - 1,
        group="tests",
    ),
    Setting(
        "SNAKEBOT_CLI_FUZZ_EXAMPLES",
        "int",
        "argument lists of the command-line fuzz test",
        default=40,
        unit="examples",
        low=1,
        high=100_000,
        group="tests",
    ),
)

SETTINGS: dict[str, Setting] = {s.name: s for s in _TABLE}
"""Every ``SNAKEBOT_*`` variable, by name."""


def setting(name: str) -> Setting:
    """The row of ``name`` (a KeyError for a name not in the table is a bug)."""
    return SETTINGS[name]


def lookup(name: str) -> Value | None:
    """The parsed value of variable ``name``, or None when it is unset or empty."""
    text = os.environ.get(name, "").strip()
    return SETTINGS[name].parse(text) if text else None


def resolve(name: str) -> Value | None:
    """The parsed value of variable ``name``, else the table's default (None if it has
    none)."""
    value = lookup(name)
    return SETTINGS[name].default if value is None else value


def resolve_int(name: str) -> int:
    value = resolve(name)
    assert isinstance(value, int) and not isinstance(value, bool), name
    return value


def resolve_float(name: str) -> float:
    value = resolve(name)
    assert isinstance(value, (int, float)) and not isinstance(value, bool), name
    return float(value)


def default_int(name: str) -> int:
    """The table's default of a whole-number variable."""
    default = SETTINGS[name].default
    assert isinstance(default, int), name
    return default


def default_float(name: str) -> float:
    """The table's default of a number variable, as a float."""
    default = SETTINGS[name].default
    assert isinstance(default, (int, float)) and math.isfinite(default), name
    return float(default)


def lookup_path(name: str) -> Path | None:
    """A ``dir``/``out_dir`` variable's path, or None when unset (the reader's default)."""
    value = lookup(name)
    assert value is None or isinstance(value, Path), name
    return value


def lookup_text(name: str) -> str | None:
    """A ``text``/``program`` variable's value, or None when unset."""
    value = lookup(name)
    assert value is None or isinstance(value, str), name
    return value


def is_set(name: str) -> bool:
    """Whether a ``flag`` variable is set (to anything not empty)."""
    return lookup(name) is True


def check_environment(skip_groups: tuple[str, ...] = ("tests",)) -> None:
    """Resolve every variable that is set (but those of ``skip_groups``):
    :class:`SettingError` for the first one whose value is unusable."""
    for name, row in SETTINGS.items():
        if row.group not in skip_groups:
            lookup(name)
