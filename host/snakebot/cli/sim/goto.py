"""``snakebot sim goto``: take the emulated robot to a target pose in closed loop."""

from __future__ import annotations

import contextlib
import math
import sys
from pathlib import Path
from typing import Any

import click

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli.options import (
    Goal,
    ideal_option,
    json_option,
    plot_option,
    robot_argument,
    target_options,
    video_option,
    world_option,
)
from snakebot.cli.output import dumps
from snakebot.cli.plan import unreachable
from snakebot.extras import require
from snakebot.model.plan import Unreachable
from snakebot.plots.video import StateMotion, check_video_path, write_video
from snakebot.sim.physics.select import require_world
from snakebot.workflows.goto import MAX_SLOWDOWN
from snakebot.workflows.goto import goto as run_goto


@click.command("goto")
@robot_argument
@target_options
@world_option()
@click.option(
    "--slowdown",
    type=click.IntRange(1, MAX_SLOWDOWN),
    help="play the frames this many times slower than the servos allow (default: 1 on the "
    "kinematic world, 3 on mujoco, where slower loops slip less)",
)
@ideal_option
@plot_option("the body's path, the poses read after each segment and the target")
@video_option("the robot's way to the target")
@json_option()
def goto(
    robot: str,
    goal: Goal,
    world: str,
    slowdown: int | None,
    ideal: bool,
    plot: Path | None,
    video: Path | None,
    video_size: tuple[int, int],
    as_json: bool,
) -> None:
    """Take the emulated ROBOT to a target pose in closed loop.

    The plan of `snakebot plan` (start -> hub, loops, back) is played segment by segment
    on the emulated bus, the host as bus master running the controller's player. After
    each segment the body's pose is read from the world, as a camera or motion capture
    would on the real robot, and the next loop is fitted again to its share of what is
    left of the way, corrected by what the world made of the loops so far (a floor that
    slips moves the body shorter or askew); loops go on until the move back would end
    within half the tolerance (five times the planned loops at most), and it gives up,
    saying why, once a pose read is farther from the target than its leash allows
    (docs/goto.md). On a physics world,
    where no route's loops keep well off singular configurations, it goes by the
    half-way pose: one closed loop there, a second from there on. The report gives
    the final error, the loops played (iterations) and the path; the exit status is 1
    if the end is outside the tolerance. On a physics world an N-link snake (snake5)
    plays whole serpenoid cycles instead of loops, each at one steering offset: after
    each it reads the pose and the joints' present positions and fits the cycles left
    again, by a model of one cycle learned as it runs. docs/goto.md has what it
    achieves on MuJoCo.

    \b
    Example:
      snakebot sim goto trident --to 2,1,30deg --plot goto.png
      snakebot sim goto trident --to 2,1,30deg --video goto.mp4 --size 640x360
    """
    require("scipy", "planning (`sim goto`)", extra="plan")
    require_world(world)
    if plot is not None:
        require("matplotlib", "--plot")
    from snakebot.model.robots import load_robot

    chosen = load_robot(robot)
    if video is not None:
        check_video_path(video)
    bar = click.progressbar(length=1, label="segments", file=sys.stderr)

    def progress(done: int, total: int) -> None:
        bar.length = total
        bar.update(1)

    try:
        with bar if not as_json else contextlib.nullcontext():
            result = run_goto(
                chosen,
                goal.target,
                world=world,
                ideal=ideal,
                slowdown=slowdown,
                **goal.settings(),
                progress=None if as_json else progress,
            )
    except Unreachable as exc:
        unreachable(exc)
        return
    summary = result.summary()
    summary.update(length_unit=chosen.length_unit, length_legend=chosen.length_legend)
    if plot is not None:
        from snakebot.plots.goto import plot_goto

        summary["plot"] = str(plot_goto(result, plot))
    if video is not None:
        click.echo("writing the video ...", err=True)
        run = StateMotion.of_states(result.path.t, result.path.q)
        summary["video"] = str(
            write_video(
                video,
                chosen,
                {f"{result.world} world": run},
                f"{chosen.name} to the target",
                size=video_size,
                say=lambda line: click.echo(line, err=True),
            )
        )
    if as_json:
        click.echo(dumps(summary, indent=2))
    else:
        _print(summary)
    if not summary["error"]["within"]:
        raise SystemExit(1)


def _print(s: dict[str, Any]) -> None:
    t, f, e = s["target"], s["final"], s["error"]
    click.echo(
        f"{s['robot']} on the {s['world']} world: {len(s['segments'])} segments "
        f"({s['iterations']} loops, each re-planned from the pose read) in "
        f"{s['duration_s']:.2f} s of bus time ({s['wall_s']:.2f} s wall)"
    )
    u = s["length_unit"]
    for label, p in (("target", t), ("reached", f)):
        click.echo(
            f"  {label:8} x = {p['x']: .4f} {u}  y = {p['y']: .4f} {u}  theta = "
            f"{math.degrees(p['theta']): .2f} deg"
        )
    verdict = "within" if e["within"] else "OUTSIDE"
    click.echo(
        f"  error {e['position']:.4g} {u} (tolerance {e['position_tolerance']:.4g} {u}), heading "
        f"{math.degrees(e['heading_rad']):.3f} deg (tolerance "
        f"{math.degrees(e['heading_tolerance_rad']):.2f} deg): {verdict} the tolerance"
    )
    if s["why"]:
        click.echo(f"  {s['why']}")
    if s["length_legend"]:
        click.echo(f"  ({s['length_legend']})")
    if "plot" in s:
        click.echo(f"plot written to {s['plot']}")
    if "video" in s:
        click.echo(f"video written to {s['video']}")
