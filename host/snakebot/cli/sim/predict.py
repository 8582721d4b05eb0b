"""``snakebot sim predict``: play a gait table or a controller program on the emulated
robot and compare the body's path with the prediction from the same file."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import click

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli.options import (
    ideal_option,
    json_option,
    mu_option,
    plot_option,
    robot_option,
    video_option,
    world_option,
)
from snakebot.cli.output import echo_json
from snakebot.cli.params import EXISTING_INPUT, NumberType
from snakebot.extras import require
from snakebot.formats.program.files import is_program_file
from snakebot.plots.video import StateMotion, check_video_path, write_video
from snakebot.workflows.predict import DEFAULT_WORLD_HZ, MAX_WORLD_HZ, predict_file


def _motion(label: str, m: dict[str, Any], unit: str) -> str:
    return (
        f"  {label:12} dx = {m['dx']: .6f} {unit}  dy = {m['dy']: .6f} {unit}  "
        f"dtheta = {m['dtheta']: .6f} rad"
    )


@click.command("predict")
@click.argument("gait_file", metavar="FILE", type=EXISTING_INPUT)
@robot_option(
    "Robot to emulate",
    otherwise="the one named in GAIT.json; for a program, the built-in robot whose joints "
    "it carries",
)
@ideal_option
@click.option(
    "--world-rate",
    type=NumberType(0, MAX_WORLD_HZ, low_open=True),
    default=DEFAULT_WORLD_HZ,
    show_default=True,
    help="how often (Hz, bus time) the world samples modelled servos; at least once per frame",
)
@world_option()
@mu_option
@plot_option("the emulated and predicted body paths and the joints' tracking")
@video_option("the emulated robot, the predicted one beside it")
@json_option()
def predict(
    gait_file: Path,
    robot: str | None,
    ideal: bool,
    world_rate: float,
    world: str,
    mu: float | None,
    plot: Path | None,
    video: Path | None,
    video_size: tuple[int, int],
    as_json: bool,
) -> None:
    """Play the gait table or controller program FILE (.gait, or .prog from `snakebot
    program build` or `snakebot plan -o X.prog`) on the emulated robot and compare the
    body's path with the prediction integrated from the same file.

    The host is the bus master, as with a USB2Dynamixel adapter and no controller: it
    puts the virtual servos at the first frame, then runs the controller's own gait
    player (the firmware's C, in process) every 10 ms control tick and sends its goals
    (interpolated between frames) and moving speeds in one SYNC_WRITE per tick.
    The servos' present positions drive the body through the minimum-slip wheel model,
    or, with --world mujoco, the servos drive a body with mass on wheels that can slip,
    and the report adds each wheel's sideways slip, each joint's energy and peak load.
    Everything runs on the emulator's clock, many times faster than real time.

    A program is run by the controller's own player in program mode (its fixed-point
    generators, one control tick at a time); the prediction takes the goals the host's
    reference of those generators gives at every program step (within a tick of the
    controller's), each step a frame, and integrates them as a table's frames.

    The report gives the body's displacement (in the start pose's frame: for a snake,
    +x along link 1 from the tail end (x, y) towards the head) emulated and
    predicted, their difference, the joints' tracking error and the wheels' slip.
    Modelled AX-12s lag their goals (carrying the body's load, as in `sim serve`); a
    table played once (a plan, a program) is held at its last frame until they come to
    rest there, and the emulated end is where they stop ("rest_s": how long that took).
    With --ideal the two paths agree to the integrator's accuracy. Where ideal wheels
    are singular on a frame interval (a rounded crossing of the 3-link snake's phi1 =
    phi2), that interval alone gets a little rolling friction, in the prediction as in
    the emulator; a prediction passing near a singular configuration (condition number
    above 100) is warned about, on stderr and in the JSON "warnings".

    \b
    Example:
      snakebot gait serpenoid snake5 -A 30deg -w 180deg -d 90deg --cycles 1 -o s.gait
      snakebot sim predict s.gait --plot s.png --video s.mp4
      snakebot plan trident --to 0.3,0.1,20deg -o go.prog
      snakebot sim predict go.prog --ideal
    """
    if video is not None:
        check_video_path(video)
    result, summary = predict_file(
        gait_file, robot, ideal=ideal, world_hz=world_rate, world=world, mu=mu
    )
    summary["length_unit"] = length = result.robot.length_unit
    if video is not None:
        click.echo("writing the video ...", err=True)
        summary["video"] = str(
            write_video(
                video,
                result.robot,
                {
                    f"emulated ({world})": result.emulated,
                    "predicted": StateMotion.of_states(result.predicted.t, result.predicted.q),
                },
                f"{gait_file.name} on {result.robot.name}",
                size=video_size,
                say=lambda line: click.echo(line, err=True),
            )
        )
    if plot is not None:
        require("matplotlib", "--plot")
        from snakebot.plots.predict import plot_prediction

        summary["plot"] = str(plot_prediction(result, plot))
    if echo_json(as_json, summary, indent=2):
        return
    diff = summary["difference"]
    em = summary["emulated"]
    unit = "program steps" if is_program_file(gait_file) else "frames"
    click.echo(
        f"played {gait_file} on the emulated {summary['robot']} in the {world} world "
        f"({summary['servos']} servos, host as bus master): {summary['frames']} "
        f"{unit} every {summary['frame_period_ms']} ms, "
        f"{'one loop' if summary['loop'] else 'once'}, {summary['duration_s']:.3f} s"
    )
    click.echo(f"body motion ({summary['frame']}):")
    click.echo(_motion("emulated:", em, length))
    click.echo(_motion("predicted:", summary["predicted"], length))
    click.echo(_motion("difference:", diff, length))
    click.echo(
        f"  paths differ by at most {diff['path_max']:.3g} {length} in position and "
        f"{diff['heading_max']:.3g} rad in heading"
    )
    if result.robot.length_legend:
        click.echo(f"  ({result.robot.length_legend})")
    click.echo(
        f"joint tracking error: max {math.degrees(diff['joint_max_rad']):.3f} deg, "
        f"rms {math.degrees(diff['joint_rms_rad']):.3f} deg"
    )
    f = em["friction"]
    click.echo(
        f"wheel slip: at most {em['slip_max']:.3g} {length}/s sideways (mu = {f['lateral']:g}, "
        f"C_rr = {f['rolling']:g}, axle {f['axle_nm']:g} N m)"
    )
    if "work_j" in em:
        click.echo(
            "physics: net work per joint "
            + ", ".join(f"{e:.3g}" for e in em["work_j"])
            + " J (below 0: driven backwards), electrical "
            + ", ".join(f"{e:.3g}" for e in em["electrical_j"])
            + " J; peak load "
            + ", ".join(f"{100 * v:.0f}" for v in em["peak_load"])
            + " % of stall; slid sideways "
            + ", ".join(f"{v:.3g}" for v in em["slip_distance"])
            + " per wheel"
        )
    click.echo(
        f"ran {summary['realtime_factor']:.0f}x faster than real time "
        f"({summary['duration_s']:.3f} s emulated in {summary['wall_s']:.3f} s)"
    )
    if plot is not None:
        click.echo(f"plot written to {summary['plot']}")
    if video is not None:
        click.echo(f"video written to {summary['video']}")
    for warning in summary["warnings"]:
        click.echo(f"warning: {warning['message']}", err=True)
