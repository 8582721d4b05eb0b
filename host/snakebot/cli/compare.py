"""`snakebot compare`: a recorded run against the gait's prediction."""

from __future__ import annotations

from pathlib import Path

import click

from snakebot.cli.options import json_option, plot_option, robot_option
from snakebot.cli.output import echo_json
from snakebot.cli.params import INPUT_PATH
from snakebot.extras import require
from snakebot.formats.gaittable import read_gait
from snakebot.workflows.compare import compare, load_run
from snakebot.workflows.predict import resolve_robot


@click.command("compare")
@click.argument("run", type=INPUT_PATH)
@click.argument("gait", type=INPUT_PATH)
@robot_option(
    "The robot whose calibration turns ticks into angles",
    otherwise="the one the gait's metadata names",
)
@plot_option("the joints and their error")
@json_option()
def compare_command(
    run: Path, gait: Path, robot: str | None, plot: Path | None, as_json: bool
) -> None:
    """Line up RUN (snakebot monitor --csv or --mcap output) against GAIT (the table that
    was played) and report how far each joint was from the prediction.

    \b
        snakebot upload walk.gait --port /dev/ttyUSB0 && snakebot play --port /dev/ttyUSB0 --loop
        snakebot monitor --port /dev/ttyUSB0 --csv run.csv --duration 6   # while it plays
        snakebot compare run.csv walk.gait --plot compare.png

    The prediction is the joint angles the table asks for (linear between frames, as the
    controller plays them). Each sample is placed in the gait by the controller's own
    record: the frame it was playing, refined by the goals it had sent (the monitor
    records both), so a host that stalled or was slow between two reads shifts nothing;
    stalls and gaps are reported. A run without them is lined up by cross-correlating
    its first joint with the prediction. Then each joint's RMS and largest error in
    degrees are reported. A run with an external pose (columns pose_x, pose_y in metres
    and pose_theta in radians, e.g. added from motion capture) is also compared with
    the body path the table's motion predicts.
    """
    recorded = load_run(run)
    table = read_gait(gait)
    result = compare(recorded, table, resolve_robot(table, robot))
    summary = {"run": str(run), "gait": str(gait), **result.summary()}
    if plot is not None:
        require("matplotlib", "--plot")
        from snakebot.plots.compare import plot_comparison

        summary["plot"] = str(plot_comparison(result, plot))
    if echo_json(as_json, summary):
        return
    click.echo(
        f"{summary['samples']} samples over {summary['duration_s']} s; the run starts "
        f"{summary['start_in_gait_s']} s into the gait (lined up by the "
        f"{summary['aligned_by']})"
    )
    for kind, what in (
        ("stalls", "the controller's frame stood still while the host's clock ran"),
        ("gaps", "no samples"),
    ):
        for e in summary[kind]:
            click.echo(f"  {kind[:-1]}: {e['length_s']} s at {e['at_s']} s ({what})")
    if summary["stalls"] and summary["aligned_by"].startswith("controller"):
        click.echo(
            "  (the comparison follows the controller's frames, so a stall does not shift it)"
        )
    for j in summary["joints"]:
        click.echo(f"  {j['joint']:>10}  RMS {j['rms_deg']:7.2f} deg   max {j['max_deg']:7.2f} deg")
    if "pose" in summary:
        p = summary["pose"]
        click.echo(f"  pose: RMS {p['rms_m']} m, max {p['max_m']} m, at the end {p['final_m']} m")
    if plot is not None:
        click.echo(f"wrote {summary['plot']}")
