"""`snakebot monitor`: watch the controller and its servos live."""

from __future__ import annotations

import contextlib
import csv
import os
import shutil
import sys
import time
from pathlib import Path
from typing import IO, Any

import click

from snakebot.cli.options import (
    ControllerLink,
    controller_options,
    foxglove_option,
    look_options,
    robot_option,
    stack,
)
from snakebot.cli.output import dumps
from snakebot.cli.params import OUTPUT_PATH
from snakebot.cli.signals import held
from snakebot.link.controller.mcap_log import McapLog
from snakebot.link.controller.monitor import CSV_COLUMNS, csv_rows, render, sample
from snakebot.userfiles import OutputRefused, open_recording
from snakebot.workflows.foxglove import SampleStream

CLEAR_BELOW = "\x1b[J"
GRID_SLACK = 1e-9
"""Lets a --duration that is a whole number of intervals count as one (0.3 / 0.1 is
2.9999999999999996 in floating point)."""


RECORD_PATH = OUTPUT_PATH
RECORDS = {
    "csv": "every sample to this CSV file, one row per servo (t, state, joint name, ticks "
    "and degrees, speed, load, voltage, temperature, errors)",
    "mcap": "every sample to this MCAP file (Foxglove, PlotJuggler): one JSON message per "
    "sample on /snakebot/telemetry, as --json prints it, and the topics --foxglove "
    "streams (/joint_states, /snakebot/servos, /snakebot/controller, /tf with --robot). "
    "Needs the mcap package",
}
"""--csv and --mcap: the recordings a run can keep, and what each holds."""


def _cursor_up(lines: int) -> str:
    return f"\x1b[{lines}F" if lines else ""


@click.command("monitor")
@controller_options
@look_options(0.5)
@stack(
    *(
        click.option(f"--{fmt}", f"{fmt}_path", type=RECORD_PATH, help=f"Also record {what}.")
        for fmt, what in RECORDS.items()
    )
)
@robot_option(
    "With --foxglove or --mcap: the robot on the controller, for the joints' efforts, its "
    "links and its pose predicted from the joint angles on /tf",
    otherwise="the joints alone",
)
@foxglove_option("the controller's state and its servos, each sample")
def monitor(
    link: ControllerLink,
    as_json: bool,
    duration: float | None,
    interval: float,
    csv_path: Path | None,
    mcap_path: Path | None,
    robot: str | None,
    foxglove: tuple[str, int] | None,
) -> None:
    """Show the controller's state and error flags, and each roster servo's position,
    load, voltage, temperature and errors, as the controller last read them.

    On a terminal the table refreshes in place; otherwise (or with --json, one JSON
    record per line: JSON Lines) every sample is printed after the last. With --csv
    each sample is also written to a file as it is taken, so a run stopped with Ctrl-C
    or SIGTERM (exit 130, 143) keeps everything up to then; --mcap does the same in
    MCAP, in chunks written every second, so even a SIGKILL loses at most the last one.
    With --foxglove each sample also goes to Foxglove as it is taken, e.g.

    \b
        snakebot monitor --port /dev/ttyUSB0 --interval 0.05 --robot snake5 --foxglove 8765
    """
    live = sys.stdout.isatty() and not as_json
    shown = 0
    view = SampleStream(robot) if foxglove is not None or mcap_path is not None else None
    # Only files this run creates may be removed again: a path that was there before
    # (a file of the user's, a device such as /dev/null) is never unlinked.
    created = [p for p in (csv_path, mcap_path) if p is not None and not os.path.lexists(p)]
    with contextlib.ExitStack() as stack:
        recorder = None
        if csv_path is not None:  # opened first: a path that cannot be written fails at once
            out = stack.enter_context(_open_record(csv_path, "--csv", text=True))
            recorder = csv.DictWriter(out, fieldnames=CSV_COLUMNS)
        mcap_log = None
        try:
            if mcap_path is not None:
                mcap_log = McapLog(stack.enter_context(_open_record(mcap_path, "--mcap")))
                stack.enter_context(mcap_log)
            ctl = stack.enter_context(link.open())
            ctl.identify()
            if foxglove is not None and view is not None:
                server = stack.enter_context(view.serve(*foxglove, name="snakebot monitor"))
                click.echo(f"Foxglove: open ws://{foxglove[0]}:{server.port}", err=True)
        except BaseException:
            stack.close()  # no controller, no recording: leave no empty file of ours
            for path in created:
                path.unlink(missing_ok=True)
            raise
        if recorder is not None:
            recorder.writeheader()
        t0 = time.monotonic()
        taken = 0
        while True:
            s = sample(ctl, t0)
            with held():  # a stop signal waits until the sample is written whole
                if recorder is not None:
                    recorder.writerows(csv_rows(s))
                    out.flush()
                if mcap_log is not None:
                    mcap_log.write(s.as_record())
                if view is not None:
                    view.send(s, mcap_log)
            if as_json:
                click.echo(dumps(s.as_record()))
            else:
                lines = render(s)
                if live:  # lines cut to the width, so none wraps and the count holds
                    width = max(20, shutil.get_terminal_size().columns - 1)
                    lines = [line[:width] for line in lines]
                    click.echo(_cursor_up(shown) + CLEAR_BELOW + "\n".join(lines))
                    shown = len(lines)
                else:
                    click.echo("\n".join(lines) + "\n")
            taken += 1
            # Sample k is due at t0 + k * interval, counted on an integer grid: comparing
            # accumulated float times would drop the last sample at random. A link slower
            # than the interval ends on the clock all the same.
            if duration is not None and (
                taken > duration / interval + GRID_SLACK or time.monotonic() - t0 > duration
            ):
                break
            wait = t0 + taken * interval - time.monotonic()
            if wait > 0:
                time.sleep(wait)  # a link slower than the interval samples back to back


def _open_record(path: Path, option: str, text: bool = False) -> IO[Any]:
    """Open a recording file (``userfiles.open_recording``: the final file, never through
    a link nor onto a device); a path that cannot be written is bad input (exit 2)."""
    try:
        return open_recording(path, text=text)
    except OutputRefused as exc:
        raise click.BadParameter(str(exc), param_hint=option) from None
    except OSError as exc:
        raise click.BadParameter(
            f"cannot write {path}: {exc.strerror or exc}; choose a file in an existing, "
            "writable directory",
            param_hint=option,
        ) from exc
