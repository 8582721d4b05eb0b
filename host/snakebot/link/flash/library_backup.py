"""Keeping the controller's gait library across `snakebot flash`.

It is not known whether the ROBOTIS bootloader's ``L`` erases the whole application area,
which holds the library (protocol/library.md), so before flashing every stored slot is
read through the running controller into a file in the user's application directory, and
afterwards, once the new firmware answers, written back where it is missing. A controller
that does not answer (no snakebot firmware yet, or a board already in its bootloader) is
skipped with a warning: flashing must not depend on it.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from snakebot.errors import SnakebotError
from snakebot.formats.protocol.errors import ProtocolError
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.errors import LibraryRefused
from snakebot.link.controller.library import backup, restore, stored_slots
from snakebot.settings import lookup_path
from snakebot.userfiles import UnreadableInput, read_text_bounded, write_atomic

BACKUP_DIR_ENV = "SNAKEBOT_LIBRARY_BACKUP_DIR"
"""Overrides where backups go (default: ``library-backups`` in click's application
directory for snakebot, e.g. ~/.config/snakebot on Linux)."""

BOOT_WAIT_S = 5.0
"""How long the new firmware may take to answer after GO before the restore gives up."""

Say = Callable[[str], None]


def backup_dir() -> Path:
    override = lookup_path(BACKUP_DIR_ENV)
    return override or Path(click.get_app_dir("snakebot")) / "library-backups"


def _answers(ctl: ControllerClient) -> bool:
    """Whether a controller answers a PING, tried three times (a busy link may drop one;
    a silent board costs only three reply timeouts, well before its user presses MODE or
    power-cycles it)."""
    try:
        ctl.link.ping(ctl.id, retries=2)
    except (ProtocolError, OSError):
        return False
    return True


def backup_library(port: str, say: Say, warn: Say) -> Path | None:
    """Save every stored slot of the controller on ``port`` to a new file; its path, or
    None if there was nothing to save or the controller did not answer."""
    try:
        with ControllerClient.open(port) as ctl:
            if not _answers(ctl):
                warn(
                    f"warning: no snakebot controller answered on {port}: its gait library "
                    "(if any) is not backed up"
                )
                return None
            ctl.identify()
            saved = backup(ctl)
    except (SnakebotError, OSError) as exc:
        warn(f"warning: the gait library could not be backed up ({exc}); flashing anyway")
        return None
    stored = stored_slots(saved)
    if not stored:
        say("The controller's gait library is empty: nothing to back up.")
        return None
    folder = backup_dir()
    folder.mkdir(parents=True, exist_ok=True)
    path = write_backup(
        saved, folder / f"library-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}.json"
    )
    say(f"Backed up {len(stored)} gait-library slot(s) to {path}")
    return path


MAX_BACKUP_BYTES = 1 << 20
"""The largest library backup read: the board's whole 512 KB flash in base64 (683 KB) and
its JSON fit."""


def write_backup(saved: dict[str, Any], path: Path) -> Path:
    """Write a backup (what :func:`snakebot.link.controller.library.backup` read) to
    ``path``, atomically."""
    return write_atomic(path, json.dumps(saved, indent=1) + "\n")


def read_backup(path: Path) -> dict[str, Any]:
    """A backup file's contents; LibraryRefused naming the problem if it is not one."""
    try:
        saved = json.loads(read_text_bounded(path, MAX_BACKUP_BYTES, "library backup"))
    except (OSError, ValueError, RecursionError, UnreadableInput) as exc:
        raise LibraryRefused(f"cannot read the library backup {path}: {exc}") from exc
    if not isinstance(saved, dict):
        raise LibraryRefused(
            f"{path} is not a snakebot library backup: pass a file `snakebot library backup` "
            "or `snakebot flash` wrote"
        )
    return saved


def restore_library(
    port: str, path: Path, say: Say, warn: Say, wait_s: float = BOOT_WAIT_S
) -> None:
    """Write the slots saved in ``path`` back to the controller on ``port`` (waiting up to
    ``wait_s`` for the new firmware to answer); warns, with the command to run later, if
    it cannot."""
    later = f"restore it later with `snakebot library restore {path} --port {port}`"
    try:
        with ControllerClient.open(port) as ctl:
            deadline = time.monotonic() + wait_s
            while not _answers(ctl):
                if time.monotonic() > deadline:
                    warn(f"warning: the new firmware did not answer on {port}: {later}")
                    return
                time.sleep(0.1)
            ctl.identify()
            written = restore(ctl, read_backup(path))
    except (SnakebotError, OSError) as exc:
        warn(f"warning: the gait library was not restored ({exc}): {later}")
        return
    if written:
        say(f"Restored {len(written)} gait-library slot(s) from {path}")
    else:
        say("The gait library survived flashing: nothing to restore.")
