"""`snakebot demo`: the main job, end to end, on the emulated robot with its real firmware."""

from __future__ import annotations

import signal
from pathlib import Path
from types import FrameType
from typing import Any

import click

from snakebot.cli.options import (
    directory_option,
    firmware_option,
    json_option,
    robot_option,
    video_option,
    wave_options,
    world_option,
)
from snakebot.cli.output import echo_json
from snakebot.plots.demo import draw_demo
from snakebot.plots.video import check_video_path
from snakebot.workflows.demo import DemoSettings, run_demo, summary_lines

EXIT_INTERRUPTED = 130  # as a shell reports a program stopped by Ctrl-C


def _sigterm(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt  # unwinds through run_demo's clean-up, like Ctrl-C


@click.command()
@robot_option("The snake to emulate", default="snake5")
@wave_options()
@click.option(
    "--cycles",
    type=click.IntRange(1, 20),
    default=3,
    show_default=True,
    help="Gait cycles measured (after one cycle to settle).",
)
@directory_option("--out", default=Path("out"), what="the gait table and the PNG")
@firmware_option
@world_option(DemoSettings.world)
@video_option("the emulated robot")
@json_option()
def demo(as_json: bool, **options: Any) -> None:
    """Run the whole chain on the emulated 5-link robot and report what it did.

    It generates a serpenoid gait table, starts the emulated robot (the real controller
    firmware under QEMU, its servo bus on emulated AX-12s, the world that moves the
    body), uploads the table over the PC link, plays it while monitoring, and compares
    how far and in which direction the body went with the prediction from the table.
    It writes OUT/demo.gait and OUT/demo.png (paths and joint angles) and leaves nothing
    running, also when interrupted. `make demo` builds everything first and runs this.
    """
    settings = DemoSettings(**options)
    if settings.video is not None:
        check_video_path(settings.video)
    say = (lambda _line: None) if as_json else click.echo
    previous = signal.signal(signal.SIGTERM, _sigterm)
    try:
        result = draw_demo(run_demo(settings, say=say), say=say)
    except KeyboardInterrupt:
        click.echo(
            "interrupted: the emulated robot (QEMU, the bus) was stopped; nothing is left running",
            err=True,
        )
        raise SystemExit(EXIT_INTERRUPTED) from None
    finally:
        signal.signal(signal.SIGTERM, previous)
    if echo_json(as_json, result.as_dict()):
        return
    for line in summary_lines(result):
        click.echo(line)
