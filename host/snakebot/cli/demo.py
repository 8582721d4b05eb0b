"""`snakebot demo`: the main job, end to end, on the emulated robot with its real firmware."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from snakebot.cli.options import (
    board_option,
    directory_option,
    firmware_option,
    json_option,
    robot_option,
    video_option,
    wave_options,
    world_option,
)
from snakebot.cli.output import echo_json
from snakebot.cli.signals import interrupted_status
from snakebot.plots.demo import draw_demo
from snakebot.plots.video import check_video_path
from snakebot.sim.physics.select import require_world
from snakebot.workflows.demo import DemoSettings, run_demo, summary_lines


@click.command()
@robot_option("The snake to emulate", default="snake5")
@wave_options()
@click.option(
    "--cycles",
    type=click.IntRange(1, 20),
    default=DemoSettings.cycles,
    show_default=True,
    help="Gait cycles measured (after one cycle to settle).",
)
@directory_option("--out", default=Path("out"), what="the gait table and the PNG")
@board_option
@firmware_option
@world_option(DemoSettings.world)
@video_option("the emulated robot")
@json_option()
def demo(as_json: bool, **options: Any) -> None:
    """Run the whole chain on the emulated 5-link robot and report what it did.

    It generates a serpenoid gait table, starts the emulated robot (the CM-530's own
    firmware image on the emulated STM32F103RE, or with --board qemu the qemu board's
    build under QEMU; its servo bus on emulated AX-12s; the world that moves the body),
    uploads the table over the PC link, plays it while monitoring, and compares how far
    and in which direction the body went with the prediction from the table.
    It writes OUT/demo.gait and OUT/demo.png (paths and joint angles) and leaves nothing
    running, also when interrupted. `make demo` builds everything first and runs this
    with its defaults; a quick look (one cycle of a faster wave, the kinematic world):

    \b
        snakebot demo -w 360deg --cycles 1 --world kinematic --out out/quick

    The verdict is AGREE or DISAGREE (exit 0), or INVALID (exit 1) when the difference
    is beyond the tolerance and the host did not give the emulator steady time (the
    firmware's goals stood still or leapt ahead in the measured cycles): the result
    then depends on the host's scheduling, so run it again on an idle machine.
    """
    settings = DemoSettings(**options)
    if settings.video is not None:
        check_video_path(settings.video)
    require_world(settings.world)
    say = (lambda _line: None) if as_json else click.echo
    try:  # SIGTERM too (snakebot.cli.signals): it unwinds through run_demo's clean-up
        result = draw_demo(run_demo(settings, say=say), say=say)
    except KeyboardInterrupt as exc:
        click.echo(
            "interrupted: the emulated robot (the board, the bus) was stopped; nothing is "
            "left running",
            err=True,
        )
        raise SystemExit(interrupted_status(exc)) from None
    if not echo_json(as_json, result.as_dict()):
        for line in summary_lines(result):
            click.echo(line)
    if result.comparison.verdict == "INVALID":
        raise SystemExit(1)
