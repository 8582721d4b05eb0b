"""`snakebot doctor`: bring-up checks on a port, each with a verdict and a fix."""

from __future__ import annotations

import sys

import click

from snakebot.cli.options import (
    ANY_PORT,
    bauds_option,
    controller_id_option,
    ids_option,
    json_option,
    port_option,
)
from snakebot.cli.output import dumps
from snakebot.formats import register_values
from snakebot.link.bus import doctor as checks
from snakebot.link.flash.settings import FlashTimeouts

MARKS = {"ok": "ok  ", "warn": "WARN", "fail": "FAIL", "skip": "skip"}


@click.command("doctor")
@port_option(ANY_PORT)
@controller_id_option
@ids_option
@bauds_option("1000000")
@click.option(
    "--bootloader",
    "check_bootloader",
    is_flag=True,
    help="Instead of the controller or the servos, check that the CM-530's bootloader "
    "answers: it asks you to press MODE or power-cycle the board, then starts the "
    "application again.",
)
@click.option(
    "--board",
    "expected_board",
    type=click.Choice([checks.ANY_BOARD, *checks.board_names()]),
    default=checks.ANY_BOARD,
    show_default=True,
    help="The board the controller should name: cm530 for the robot and `snakebot sim "
    "serve` (its default board), qemu for `sim serve --board qemu`; any accepts either (and "
    "says which answered).",
)
@json_option()
def doctor(
    port: str,
    controller_id: int,
    ids: str,
    bauds: str,
    check_bootloader: bool,
    expected_board: str,
    as_json: bool,
) -> None:
    """Check a robot's wiring and settings before a first run.

    \b
        snakebot doctor --port /dev/ttyUSB0             # the CM-530, or a servo bus
        snakebot doctor --port /dev/ttyUSB0 --bootloader  # real hardware only: press MODE

    Checks, each ok / WARN / FAIL with what to do: the USB adapter's latency timer (an
    FTDI adapter's, through /sys); then, if a snakebot controller answers PING at --id
    (57600 baud), its model, firmware version, the board its firmware was built for
    (against --board; a QEMU image answering on a hardware port is a warning) and its
    state; otherwise the port is taken
    for a servo bus and scanned at --bauds: the rates servos answer at, IDs two servos
    share, and each servo's model, firmware, return delay, voltage and temperature
    (against the servo's own limits) and torque limit. Exit status 1 if any check fails.
    """
    id_list = register_values.parse_ids(ids)
    rates = register_values.parse_bauds(bauds)
    out = sys.stderr if as_json else sys.stdout
    found = [checks.adapter(port)]
    board = None
    if check_bootloader:
        click.echo("Press MODE on the CM-530 or power-cycle it now.", file=out)
        found.append(checks.bootloader(port, FlashTimeouts.resolve()))
    else:
        on_controller = checks.controller(port, controller_id, expected_board)
        if on_controller is not None:
            found += on_controller.checks
            board = on_controller.board
        else:
            click.echo(
                f"No controller at ID {controller_id}: scanning a servo bus at "
                f"{', '.join(map(str, rates))} bit/s...",
                file=out,
            )
            found += checks.servo_bus(port, id_list, rates)
    failed = [c.name for c in found if c.verdict == "fail"]
    if as_json:
        report = {"port": port, "ok": not failed, "board": board}
        click.echo(dumps({**report, "checks": [c.as_dict() for c in found]}))
    else:
        for c in found:
            click.echo(f"{MARKS[c.verdict]}  {c.name}: {c.detail}")
            if c.fix:
                click.echo(f"      fix: {c.fix}")
    if failed:
        click.echo(
            f"error: {len(failed)} check(s) failed ({', '.join(failed)}): see the fixes", err=True
        )
        sys.exit(1)
