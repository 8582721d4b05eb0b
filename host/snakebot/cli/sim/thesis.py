"""`snakebot sim thesis` and `snakebot sim friction`: the physics world's studies."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import click

from snakebot.cli.options import (
    directory_option,
    json_option,
    mu_option,
    plot_option,
    robot_option,
    video_option,
)
from snakebot.cli.output import dumps, echo_json
from snakebot.cli.params import EXISTING_INPUT, LazyChoice
from snakebot.extras import require
from snakebot.sim.physics.select import require_world

if TYPE_CHECKING:
    from snakebot.workflows.thesis import ThesisRun


@click.command("thesis")
@directory_option("--output", "-o", default=Path("out/thesis"), what="one PNG per run (NAME.png)")
@click.option(
    "--only",
    type=LazyChoice("snakebot.workflows.thesis", "RUN_NAMES"),
    multiple=True,
    help="Run only this one (repeatable); default: every run.",
)
@mu_option
@video_option(
    "each run, both worlds overlaid (FILE for one run; for several, FILE's name with -NAME added)"
)
@json_option()
def thesis(
    out_dir: Path,
    only: tuple[str, ...],
    mu: float | None,
    video: Path | None,
    video_size: tuple[int, int],
    as_json: bool,
) -> None:
    """Rerun the thesis's chapter 4 simulations in the kinematic and the MuJoCo world.

    \b
    g1, g2, g3  the trident driven along one control field (u_i = 1) for 2 s
    h1, h2, h3  its periodic inputs (A, omega) = (0.3, 3), (0.2, 3), (0.25, 2)
                on the input pairs (1,2), (1,3), (2,3) for 2 x 2.5 pi/omega
    serpenoid   the 3-link snake's serpenoid of the thesis's Figure 20

    Each run is played as a gait table on the emulated robot (host as bus master),
    once in each world, with the thesis's own settings, including the run times that
    are not whole periods (which `gait field` refuses). The trident and the 3-link
    snake are dimensionless; the physics world builds their physical twins from the
    [physics] tables of their robot files. Writes OUT/NAME.png: x, y, theta and the
    joints against t, both worlds overlaid, the model's ideal path dashed.
    docs/thesis.md compares the results with what the thesis saw. Two of the runs:

    \b
        snakebot sim thesis --only h1 --only g1 -o out/thesis
    """
    require_world("mujoco")
    require("matplotlib", "`sim thesis` (its pictures)")
    from snakebot.plots.thesis import thesis_study
    from snakebot.workflows.thesis import thesis_runs

    runs = thesis_runs(only)

    def started(i: int, run: ThesisRun) -> None:
        click.echo(f"[{i}/{len(runs)}] {run.name} on {run.robot} ...", err=as_json, nl=False)

    def finished(summary: dict) -> None:
        click.echo(" done", err=as_json)
        if not as_json:
            for line in _run_lines(summary):
                click.echo(line)

    summaries = thesis_study(
        runs,
        out_dir,
        mu=mu,
        video=video,
        video_size=video_size,
        say=lambda line: click.echo(line, err=True),
        started=started,
        finished=finished,
    )
    if as_json:
        click.echo(dumps({"runs": summaries}, indent=2))


def _run_lines(s: dict) -> list[str]:
    def state(d: dict) -> str:
        phi = ", ".join(f"{v:+.2f}" for v in d["phi"])
        return f"x {d['x']:+.3f}  y {d['y']:+.3f}  theta {d['theta']:+.3f}  phi ({phi})"

    lines = [f"  thesis saw: {s['thesis_observed']}"]
    if "model" in s:
        lines.append(f"  model     : {state(s['model'])}")
    for world in ("kinematic", "mujoco"):
        if world in s:
            lines.append(f"  {world:10}: {state(s[world])}")
    if s["clipped_frames"]:
        lines.append(f"  {s['clipped_frames']} of {s['frames']} frames clipped at the joint limits")
    lines.append(f"  wrote {s['png']}" + (f" and {s['video']}" if "video" in s else ""))
    return lines


@click.command("friction")
@click.argument("gait_file", metavar="GAIT", type=EXISTING_INPUT)
@robot_option("Robot to emulate", otherwise="the one named in GAIT.json")
@click.option(
    "--mu",
    default="0.02,0.05,0.1,0.2,0.5,1,2,5,10",
    show_default=True,
    help="Friction coefficients to try, comma-separated.",
)
@plot_option("the distance per cycle against mu, and the wheels' sideways slide")
@json_option()
def friction(gait_file: Path, robot: str | None, mu: str, plot: Path | None, as_json: bool) -> None:
    """Play GAIT in the MuJoCo world over a range of wheel-floor friction coefficients
    and compare its distance per cycle with the kinematic world's.

    Both worlds take the robot's [friction] with its lateral coefficient mu varied: the
    kinematic world without inertia (quasi-static Coulomb), MuJoCo with it. As mu falls
    the wheels slide and the snake goes less far.

    \b
    Example:
      snakebot gait serpenoid snake5 -A 30deg -w 180deg -d 90deg --cycles 1 -o s.gait
      snakebot sim friction s.gait --plot friction.png
    """
    require_world("mujoco")
    if plot is not None:
        require("matplotlib", "--plot")
    from snakebot.formats.gaittable import read_gait
    from snakebot.plots.thesis import plot_friction
    from snakebot.workflows.friction import friction_study, parse_mu_values

    values = parse_mu_values(mu)
    table = read_gait(gait_file)

    def progress(mu: float, _result: object) -> None:
        click.echo(f"  mu = {mu:g} done", err=True)

    study = friction_study(table, robot, values, str(gait_file), progress)
    if plot is not None:
        study["plot"] = str(plot_friction(study, plot))
    if echo_json(as_json, study, indent=2):
        return
    u = study["units"]
    kin, free = study["kinematic"], study["kinematic_free_wheels"]
    click.echo(
        f"{gait_file} on {study['robot']}: distance per cycle ({u}), the last of "
        f"{study['passes']} passes"
    )
    click.echo(
        f"  kinematic world, mu = {study['friction']['lateral']:g}: {kin['distance_per_cycle']:.4f}"
    )
    click.echo(f"  the table's joints, free wheels: {free['distance_per_cycle']:.4f}")
    for p in study["points"]:
        ratio = (
            p["distance_per_cycle"] / free["distance_per_cycle"]
            if free["distance_per_cycle"]
            else math.nan
        )
        click.echo(
            f"  MuJoCo, mu = {p['mu']:<6g}     {p['distance_per_cycle']:.4f} "
            f"({100 * ratio:.0f} % of free wheels), slid {p['slip_distance_per_cycle']:.4f}; "
            f"quasi-static on its joints {p['kinematic_on_physics_joints_per_cycle']:.4f}"
        )
    if plot is not None:
        click.echo(f"plot written to {study['plot']}")
