"""`snakebot library list|store|play|delete|backup|restore`: the gait library kept in the
controller's flash (protocol/library.md)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from snakebot.cli.options import ControllerLink, controller_options
from snakebot.cli.output import dumps
from snakebot.cli.params import INPUT_PATH, OUTPUT_PATH
from snakebot.formats.gaittable import read_gait
from snakebot.link.controller.library import (
    IN_RAM,
    backup,
    delete_slot,
    library_memory,
    list_slots,
    play_slot,
    restore,
    store_slot,
    store_state,
    stored_slots,
)
from snakebot.link.flash.library_backup import read_backup, write_backup

SLOT = click.argument("slot", type=click.IntRange(0, 255), metavar="SLOT")

WAITING = {
    "TABLE": "waiting for the controller to finish saving its active table",
    "LIBRARY": "the controller is writing the slot to its flash",
}


class FlashWait:
    """Shows the controller's flash write on stderr while a command waits for it: a bar
    on a terminal, else one line per kind of write (nothing with --json)."""

    def __init__(self, quiet: bool) -> None:
        self.quiet = quiet
        self.tty = sys.stderr.isatty()
        self.state = ""
        self.bar: Any = None

    def __call__(self, state: str, percent: int) -> None:
        if self.quiet:
            return
        if state != self.state:
            self.close()
            self.state = state
            label = WAITING.get(state, f"waiting for the controller ({state})")
            if not self.tty:
                click.echo(f"{label} ...", err=True)
                return
            self.bar = click.progressbar(length=100, label=label, file=sys.stderr)
            self.bar.__enter__()
        if self.bar is not None:
            self.bar.update(percent - self.bar.pos)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None


@click.group("library")
def library() -> None:
    """The gait library: named gait tables kept in the controller's flash, in slots
    that survive power-off, so the robot can walk without a PC: on the CM-530, U and D
    pick a slot (the AUX, MANAGE and PROGRAM LEDs show its number in binary) and START
    plays it or stops.

    \b
        snakebot gait serpenoid snake5 -A 30deg -w 180deg -d 90deg --cycles 2 -o walk.gait
        snakebot library store 0 walk.gait --name "walk" --port /dev/ttyUSB0
        snakebot library list --port /dev/ttyUSB0
        snakebot library play 0 --port /dev/ttyUSB0
        snakebot library backup my-library.json --port /dev/ttyUSB0
        snakebot library delete 0 --port /dev/ttyUSB0
        snakebot library restore my-library.json --port /dev/ttyUSB0

    The CM-530 has 8 slots, written to flash a step per control tick while the robot
    keeps moving: store, delete and play wait for a write under way (the controller's
    own save of a newly uploaded table, too) and show its progress. The QEMU firmware
    keeps its library in RAM: one slot, which is its active table, lost at power-off.
    """


@library.command("list")
@controller_options
def list_command(link: ControllerLink, as_json: bool) -> None:
    """Every slot: its name, kind, length, CRC-32, and whether its bytes are whole
    (DAMAGED: the flash no longer matches the CRC; store the table again), and where
    the library is kept (--json: memory FLASH, or RAM on the QEMU board). While the
    controller writes its flash (a store under way), says so: the slot being stored
    shows its previous content until the write ends."""
    with link.open() as ctl:
        ctl.identify()
        slots = list_slots(ctl)
        writing = store_state(ctl)
        memory = library_memory(ctl)
    if as_json:
        listed = {"slots": [s.as_dict() for s in slots], "memory": memory}
        click.echo(dumps({**listed, "store": writing.as_dict()}))
        return
    if not slots:
        click.echo("this controller has no gait library")
    for s in slots:
        click.echo(s.line())
    if memory == "RAM":
        click.echo(f"({IN_RAM})")
    if writing.state != "IDLE":
        click.echo(writing.line())


@library.command("store")
@SLOT
@click.argument("gait", type=INPUT_PATH)
@click.option(
    "--name",
    "-n",
    help="The slot's name, up to 16 printable ASCII characters (default: the file's name).",
)
@controller_options
def store_command(
    slot: int, gait: Path, name: str | None, link: ControllerLink, as_json: bool
) -> None:
    """Keep the gait table GAIT (a .gait file from `snakebot gait`) in slot SLOT,
    replacing what it held. The table is checked as `snakebot upload` checks it; the
    active table is left alone. A power cut while storing leaves the slot as it was or
    as stored, and every other slot untouched."""
    blob = read_gait(gait).encode()  # a bad file fails here, before the port is opened
    wait = FlashWait(as_json)
    try:
        with link.open() as ctl:
            ctl.identify()
            name = name if name is not None else gait.stem
            stored = store_slot(ctl, slot, name, blob, on_progress=wait)
    finally:
        wait.close()
    click.echo(dumps(stored.as_dict()) if as_json else f"stored: {stored.line()}")


@library.command("play")
@SLOT
@controller_options
def play_command(slot: int, link: ControllerLink, as_json: bool) -> None:
    """Make slot SLOT's table the active one and play it (stop with `snakebot stop`).
    The table played is not written over the controller's saved active table; while the
    controller is still saving a table just uploaded, this waits for the save to finish
    (playing would replace the table being saved)."""
    wait = FlashWait(as_json)
    try:
        with link.open() as ctl:
            ctl.identify()
            state = play_slot(ctl, slot, on_progress=wait)
    finally:
        wait.close()
    click.echo(dumps({"slot": slot, "state": state}) if as_json else f"slot {slot}: {state}")


@library.command("delete")
@SLOT
@controller_options
def delete_command(slot: int, link: ControllerLink, as_json: bool) -> None:
    """Empty slot SLOT (waiting, as store does, for a flash write under way)."""
    wait = FlashWait(as_json)
    try:
        with link.open() as ctl:
            ctl.identify()
            delete_slot(ctl, slot, on_progress=wait)
    finally:
        wait.close()
    click.echo(dumps({"slot": slot, "deleted": True}) if as_json else f"slot {slot} emptied")


@library.command("backup")
@click.argument("backup_file", metavar="FILE", type=OUTPUT_PATH)
@controller_options
def backup_command(backup_file: Path, link: ControllerLink, as_json: bool) -> None:
    """Save every stored slot of the controller's library to FILE (JSON: each slot's
    name, kind and bytes), for `snakebot library restore` on this controller or
    another. `snakebot flash` makes one by itself before it flashes."""
    with link.open() as ctl:
        ctl.identify()
        saved = backup(ctl)
    write_backup(saved, backup_file)
    stored = stored_slots(saved)
    if as_json:
        click.echo(dumps({"file": str(backup_file), "slots": len(stored)}))
    else:
        click.echo(f"saved {len(stored)} stored slot(s) to {backup_file}")


@library.command("restore")
@click.argument("backup_file", metavar="FILE", type=INPUT_PATH)
@controller_options
def restore_command(backup_file: Path, link: ControllerLink, as_json: bool) -> None:
    """Write the slots saved in FILE (a backup `snakebot library backup` or `snakebot
    flash` made) back to the controller, each where it is not already in place."""
    saved = read_backup(backup_file)  # a bad file fails here, before the port is opened
    with link.open() as ctl:
        ctl.identify()
        written = restore(ctl, saved)
    if as_json:
        click.echo(dumps({"restored": [s.as_dict() for s in written]}))
    else:
        click.echo(f"restored {len(written)} slot(s)")
        for s in written:
            click.echo(s.line())
