"""`snakebot demo`: the main job, end to end, on the emulated robot with its real firmware."""

from __future__ import annotations

import signal
from pathlib import Path
from types import FrameType

import click

from snakebot.cli.output import dumps
from snakebot.cli.params import OUTPUT_PATH, wave_options
from snakebot.plots.demo import draw_demo
from snakebot.plots.video import check_video_path
from snakebot.sim.physics.select import WORLDS, require_world
from snakebot.workflows.demo import DemoSettings, run_demo, summary_lines

EXIT_INTERRUPTED = 130  # as a shell reports a program stopped by Ctrl-C


def _sigterm(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt  # unwinds through run_demo's clean-up, like Ctrl-C


@click.command()
@click.option(
    "--robot",
    "-r",
    default="snake5",
    show_default=True,
    help="The snake to emulate: snake5, snake3 or a robot TOML file.",
)
@wave_options
@click.option(
    "--cycles",
    type=click.IntRange(1, 20),
    default=3,
    show_default=True,
    help="Gait cycles measured (after one cycle to settle).",
)
@click.option(
    "--out",
    "out_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("out"),
    show_default=True,
    help="Directory for the gait table and the PNG.",
)
@click.option(
    "--firmware",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Firmware image for QEMU (default: the qemu board's firmware.elf that `make "
    "firmware` built in this checkout, else the one shipped with snakebot).",
)
@click.option(
    "--world",
    type=click.Choice(WORLDS),
    default=DemoSettings.world,
    show_default=True,
    help="mujoco: the body has mass and its wheels can slip, so the prediction is checked "
    "against physics; kinematic: the body follows the prediction's own model.",
)
@click.option(
    "--video",
    type=OUTPUT_PATH,
    help="Write a GIF (or MP4, with ffmpeg) of the emulated robot seen from above.",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the results as one JSON object instead of the report.",
)
def demo(
    robot: str,
    amplitude: float,
    omega: float,
    delta: float,
    cycles: int,
    out_dir: Path,
    firmware: Path | None,
    world: str,
    video: Path | None,
    as_json: bool,
) -> None:
    """Run the whole chain on the emulated 5-link robot and report what it did.

    It generates a serpenoid gait table, starts the emulated robot (the real controller
    firmware under QEMU, its servo bus on emulated AX-12s, the world that moves the
    body), uploads the table over the PC link, plays it while monitoring, and compares
    how far and in which direction the body went with the prediction from the table.
    It writes OUT/demo.gait and OUT/demo.png (paths and joint angles) and leaves nothing
    running, also when interrupted. `make demo` builds everything first and runs this.
    """
    settings = DemoSettings(
        robot=robot,
        amplitude=amplitude,
        omega=omega,
        delta=delta,
        cycles=cycles,
        out_dir=out_dir,
        firmware=firmware,
        world=world,
        video=video,
    )
    require_world(world)
    if video is not None:
        check_video_path(video)
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
    if as_json:
        click.echo(dumps(result.as_dict()))
        return
    for line in summary_lines(result):
        click.echo(line)
