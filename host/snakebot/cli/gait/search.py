"""``snakebot gait search``: which serpenoid goes farthest (per cycle, per second, per
joule) or slides least, in either world, on this machine or a Dask cluster."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import click

from snakebot.cli.options import json_option, plot_option, rate_option, robot_argument, world_option
from snakebot.cli.output import echo_json
from snakebot.cli.params import OUTPUT_PATH, NumberType
from snakebot.extras import require
from snakebot.sim.physics.select import require_world
from snakebot.userfiles import OutputRefused, same_file
from snakebot.workflows.search import (
    METHODS,
    OBJECTIVES,
    Request,
    Search,
    Settings,
    Space,
    make_runner,
)
from snakebot.workflows.search.report import best_gait_path, search_robot, summarise, write_best
from snakebot.workflows.search.results import check_path
from snakebot.workflows.search.runner import MAX_WORKERS
from snakebot.workflows.search.space import MAX_RUNS

PATH = click.Path(dir_okay=False, path_type=Path)

CYCLES = NumberType(0, 1000, low_open=True)
"""Cycles per run: at most 1000, so one run stays bounded (a grid multiplies it)."""


def _require_extras(
    world: str, method: str, cluster: str | None, output: Path | None, plot: Path | None
) -> None:
    """Every optional package the search will need, checked before it starts (a search
    that ends in a missing package loses its results)."""
    require_world(world)
    if method == "cma":
        require("cma", "--method cma")
    if cluster is not None:
        require("distributed", "--cluster")
    if output is not None and output.suffix.lower() == ".parquet":
        require("pyarrow", "a .parquet results table (or write .csv)")
    if plot is not None:
        require("matplotlib", "--plot")


@click.command("search")
@robot_argument
@click.option(
    "--param",
    "params",
    multiple=True,
    metavar="NAME=LOW:HIGH:COUNT",
    help="a serpenoid parameter (A, omega, delta, offset): NAME=VALUE fixes it, "
    "NAME=LOW:HIGH:COUNT sweeps COUNT values, NAME=LOW:HIGH is a range for random/cma; "
    "angles in rad or with 'deg' (omega: rad/s or deg/s). Repeat for each parameter",
)
@click.option(
    "--robust",
    multiple=True,
    metavar="NAME=LOW:HIGH:COUNT",
    help="run every candidate over these values and score its worst: mu (alias "
    "friction.lateral) or rolling (alias friction.rolling) in either world, mass (a factor "
    "on every link's and wheel's mass) in the mujoco world. Repeat for several",
)
@click.option(
    "--objective",
    type=click.Choice(list(OBJECTIVES)),
    default="distance",
    show_default=True,
    help="distance per cycle, speed, distance per joule (mujoco), or slip (least sideways "
    "slide per distance)",
)
@world_option()
@click.option("--method", type=click.Choice(METHODS), default="grid", show_default=True)
@click.option(
    "--samples",
    type=click.IntRange(1, MAX_RUNS),
    default=100,
    show_default=True,
    help="random: how many candidates; cma: the budget of candidates",
)
@click.option(
    "--seed", type=click.IntRange(min=1), default=1, show_default=True, help="random/cma seed"
)
@click.option(
    "--cycles",
    type=CYCLES,
    default=3.0,
    show_default=True,
    help="gait cycles per run",
)
@rate_option
@click.option(
    "--workers",
    type=click.IntRange(1, MAX_WORKERS),
    help="processes on this machine (default: one per core; 1 runs in this process; "
    f"at most {MAX_WORKERS}, each holds its own world)",
)
@click.option(
    "--cluster",
    metavar="tcp://HOST:8786",
    help="run on this Dask distributed scheduler instead of this machine",
)
@click.option(
    "--output",
    "-o",
    type=OUTPUT_PATH,
    help="results table, .parquet or .csv (one row per run); an existing one is resumed: "
    "finished runs are skipped",
)
@click.option(
    "--best",
    "best_path",
    type=OUTPUT_PATH,
    help="write the best gait here (default with -o: RESULTS.best.gait)",
)
@plot_option("the scores: a heat map (grid) or a Pareto plot")
@json_option()
def search_command(
    robot: str,
    params: tuple[str, ...],
    robust: tuple[str, ...],
    objective: str,
    world: str,
    method: str,
    samples: int,
    seed: int,
    cycles: float,
    rate: float,
    workers: int | None,
    cluster: str | None,
    output: Path | None,
    best_path: Path | None,
    plot: Path | None,
    as_json: bool,
) -> None:
    """Search serpenoid gaits phi_k(t) = A sin(omega t + (k-1) delta) + offset for ROBOT.

    Every candidate is limit-checked as `gait serpenoid` does and played for --cycles
    cycles in the chosen world, once per --robust value; its score is its objective at
    the worst of those. A failed run (limits, a singular motion, a physics blow-up) is a
    row with its reason. The best gait is written as a .gait ready to upload.

    Example: snakebot gait search snake5 --param A=10deg:50deg:5
    --param delta=30deg:150deg:7 --param omega=360deg -o runs.parquet --plot runs.png
    """
    _require_extras(world, method, cluster, output, plot)
    if output is not None:
        check_path(output)
    best_path = best_gait_path(best_path, output)
    for path in (best_path, plot):
        if path is not None and output is not None and path != output and same_file(path, output):
            raise OutputRefused(f"{path} is also the results table -o: give each its own file")
    robot_obj = search_robot(robot)
    settings = Settings(robot_obj.source or robot, world, cycles, rate)
    request = Request(
        settings, Space.parse(params, robust), objective, method, samples, seed, output
    )
    request.check()
    runner = make_runner(workers, cluster)
    try:
        with click.progressbar(
            length=1, label=f"{method} search ({world} world)", file=sys.stderr
        ) as bar:

            def progress(done: int, total: int) -> None:
                bar.length = max(total, done, 1)
                bar.update(done - bar.pos)

            outcome = Search(request, runner, progress).run()
    finally:
        runner.close()
    summary = summarise(outcome, request, runner.workers)
    if best_path is not None and write_best(outcome, robot_obj, request, best_path):
        summary["best_gait"] = str(best_path)
    if plot is not None:
        from snakebot.plots.search import plot_search

        summary["plot"] = str(plot_search(outcome, request, plot))
    if echo_json(as_json, summary, indent=2):
        return
    _print(summary)


def _print(s: dict[str, Any]) -> None:
    click.echo(
        f"{s['method']} search of {s['robot']} in the {s['world']} world: "
        f"{s['candidates']} candidates ({s['failed']} failed), {s['runs_evaluated']} runs "
        f"evaluated, {s['runs_reused']} reused, {s['wall_s']:.1f} s on {s['workers']} workers"
    )
    best = s["best"]
    if best is None:
        click.echo("no candidate succeeded: see the reasons in the results table")
    else:
        p = best["parameters"]
        click.echo(
            f"best {s['metric']} = {best[s['metric']]:.6g}: A = {math.degrees(p['amplitude']):.2f} "
            f"deg, omega = {math.degrees(p['omega']):.2f} deg/s, delta = "
            f"{math.degrees(p['delta']):.2f} deg, offset = {math.degrees(p['offset']):.2f} deg"
        )
        figures = [
            f"{k} {best[k]:.3g}"
            for k in ("slip_ratio", "torque_nm", "torque_ratio", "lateral_ratio")
            if best.get(k) is not None
        ]
        if figures:
            click.echo("  " + ", ".join(figures))
    if s.get("on_edge"):
        click.echo(
            f"warning: the best candidate sits on the edge of the searched range of "
            f"{', '.join(s['on_edge'])}: the optimum may lie beyond it; widen the range"
        )
    for key, label in (("results", "results"), ("best_gait", "best gait"), ("plot", "plot")):
        if s.get(key):
            click.echo(f"{label} written to {s[key]}")
