"""`snakebot upload`: send a gait table (or a program) to the controller and make it the
active one."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from snakebot.cli.options import ControllerLink, controller_options
from snakebot.cli.output import dumps
from snakebot.formats.gaittable import GaitTable, read_gait
from snakebot.formats.program import Program
from snakebot.formats.program.files import is_program_file, read_program
from snakebot.link.controller.upload import UploadReport, upload_gait


@click.command("upload")
@click.argument("gait", type=click.Path(dir_okay=False, path_type=Path))
@controller_options
@click.option(
    "--new-servos",
    is_flag=True,
    help="Accept servos the controller's roster does not list (the table's servos "
    "become the roster).",
)
def upload(gait: Path, link: ControllerLink, as_json: bool, new_servos: bool) -> None:
    """Upload the gait table GAIT (a .gait file from `snakebot gait`) to the controller,
    or a program (a .prog file from `snakebot program build`), which takes the table's
    place; `snakebot play` then runs whichever is active.

    The table is checked against what the controller takes (its Table Capacity) and the
    servos it knows (its roster); those questions travel with the first chunks, and the
    commit waits for their answers, so a table that fails them is never made active.
    The chunks are sent with several in flight, each acknowledged; lost or damaged ones
    make the whole table go again (SNAKEBOT_UPLOAD_RETRIES times, default 3). Success is
    reported only once the controller's own CRC-32 and size of its active table, read
    right after the commit, equal the file's. If the upload fails, the controller keeps
    its previous table.

    The report gives the rate of the whole command (checks, transfer, verification) and
    its share of what the link's baud rate allows; a link that carried the bytes faster
    than that (a pty to the emulator) is not paced, and --json then says "paced": false
    instead of giving a "wire_percent".

    \b
        snakebot gait serpenoid snake5 -A 30deg -w 180deg -d 90deg --cycles 2 -o walk.gait
        snakebot upload walk.gait --port /dev/ttyUSB0
        snakebot play --port /dev/ttyUSB0
    """
    # a bad file fails here, before the port is opened
    table: GaitTable | Program = read_program(gait) if is_program_file(gait) else read_gait(gait)
    err = sys.stderr
    show_bar = not as_json and err.isatty()
    bar: Any = None

    def on_progress(done: int, total: int) -> None:
        nonlocal bar
        if not show_bar:
            return
        if bar is None:
            bar = click.progressbar(
                length=total, label=f"Uploading {gait.name}", file=err, show_pos=True
            )
            bar.__enter__()
        bar.update(done - bar.pos)

    def on_retry(attempt: int, attempts: int, why: str) -> None:
        nonlocal bar
        if bar is not None:
            bar.__exit__(None, None, None)
            bar = None
        click.echo(f"{why}: sending the table again (attempt {attempt} of {attempts})", err=True)

    try:
        with link.open() as ctl:
            report = upload_gait(
                ctl, table, allow_new_servos=new_servos, on_progress=on_progress, on_retry=on_retry
            )
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    _print(report, gait, link.port, as_json, table)


def _print(
    report: UploadReport, gait: Path, port: str, as_json: bool, table: GaitTable | Program
) -> None:
    program = isinstance(table, Program)
    if as_json:
        kind = "program" if program else "table"
        click.echo(dumps({"file": str(gait), "port": port, "kind": kind, **report.as_dict()}))
        return
    click.echo(report.summary())
    if isinstance(table, Program):
        click.echo(
            f"The controller confirmed it: its active program has the file's size and "
            f"CRC-32 (0x{report.crc:08x}): {len(table.segments)} segments for "
            f"{report.joints} joints, a step every {report.period_ms} ms, "
            f"{table.duration_s:.2f} s in all."
        )
    else:
        how = "looping" if report.loop else "played once"
        click.echo(
            f"The controller confirmed it: its active table has the file's size and file "
            f"CRC-32 (0x{report.crc:08x}, not the header CRC): {report.frames} frames x "
            f"{report.joints} joints every "
            f"{report.period_ms} ms, {how}."
        )
    if report.attempts > 1:
        click.echo(f"(took {report.attempts} attempts: see the messages above)")
    if not report.roster_before:
        click.echo(
            "note: the controller knew no servos before (empty roster); the table's "
            "servos are its roster now."
        )
    if report.new_servos:
        ids = ", ".join(str(i) for i in report.new_servos)
        click.echo(f"note: servo {ids} joined the roster (it had {report.roster_before}).")
    if report.playback_stopped:
        click.echo(
            "note: the commit stopped the gait that was running; start the new table "
            f"with `snakebot play --port {port}`."
        )
