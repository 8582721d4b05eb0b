"""``snakebot gait search``: which serpenoid goes farthest (per cycle, per second, per
joule) or slides least, in either world, on this machine or a Dask cluster."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import click

from snakebot.cli.output import dumps
from snakebot.cli.params import NumberType
from snakebot.formats.gaittable import write_gait
from snakebot.model.gait import serpenoid
from snakebot.model.robots import load_robot
from snakebot.sim.physics.select import WORLDS
from snakebot.workflows.search import (
    METHODS,
    OBJECTIVES,
    Request,
    Search,
    SearchError,
    Settings,
    Space,
    make_runner,
)
from snakebot.workflows.search.results import check_path
from snakebot.workflows.search.search import Outcome

PATH = click.Path(dir_okay=False, path_type=Path)


POSITIVE = NumberType(0, low_open=True)


@click.command("search")
@click.argument("robot", metavar="ROBOT")
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
@click.option("--world", type=click.Choice(WORLDS), default="kinematic", show_default=True)
@click.option("--method", type=click.Choice(METHODS), default="grid", show_default=True)
@click.option(
    "--samples",
    type=click.IntRange(min=1),
    default=100,
    show_default=True,
    help="random: how many candidates; cma: the budget of candidates",
)
@click.option(
    "--seed", type=click.IntRange(min=1), default=1, show_default=True, help="random/cma seed"
)
@click.option("--cycles", type=POSITIVE, default=3.0, show_default=True, help="gait cycles per run")
@click.option(
    "--rate", type=POSITIVE, default=50.0, show_default=True, help="table frame rate (Hz)"
)
@click.option(
    "--workers",
    type=click.IntRange(min=1),
    help="processes on this machine (default: one per core; 1 runs in this process)",
)
@click.option(
    "--cluster",
    metavar="tcp://HOST:8786",
    help="run on this Dask distributed scheduler instead of this machine",
)
@click.option(
    "--output",
    "-o",
    type=PATH,
    help="results table, .parquet or .csv (one row per run); an existing one is resumed: "
    "finished runs are skipped",
)
@click.option(
    "--best",
    "best_path",
    type=PATH,
    help="write the best gait here (default with -o: RESULTS.best.gait)",
)
@click.option("--plot", type=PATH, help="write a heat map (grid) or Pareto plot (PNG)")
@click.option("--json", "as_json", is_flag=True, help="print the summary as JSON")
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
    if output is not None:
        check_path(output)
    if best_path is None and output is not None:
        best_path = output.with_name(output.stem + ".best.gait")
    robot_obj = load_robot(robot)
    if robot_obj.kind != "snake":
        raise SearchError(
            f"{robot_obj.name} is a {robot_obj.kind}: the search tries serpenoid gaits, which "
            "drive a chain of links; give a snake (snake3, snake5 or a .toml)"
        )
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
    summary = _summary(outcome, request, runner.workers)
    best = outcome.best
    if best is not None and best_path is not None:
        p = best.point
        g = serpenoid(
            robot_obj,
            p["amplitude"],
            p["omega"],
            p["delta"],
            offset=p["offset"],
            cycles=cycles,
            rate_hz=rate,
        )
        write_gait(best_path, g.gait_table())
        summary["best_gait"] = str(best_path)
    if plot is not None:
        from snakebot.plots.search import plot_search

        summary["plot"] = str(plot_search(outcome, request, plot))
    if as_json:
        click.echo(dumps(summary, indent=2))
        return
    _print(summary)


def _summary(outcome: Outcome, request: Request, workers: int) -> dict[str, Any]:
    best = outcome.best
    failed = sum(1 for c in outcome.candidates if c.score is None)
    metric, sense = OBJECTIVES[request.objective]
    return {
        "robot": request.settings.robot,
        "world": request.settings.world,
        "method": request.method,
        "objective": request.objective,
        "metric": metric,
        "candidates": len(outcome.candidates),
        "failed": failed,
        "runs_evaluated": outcome.evaluated,
        "runs_reused": outcome.reused,
        "workers": workers,
        "wall_s": round(outcome.wall_s, 3),
        "results": str(request.output) if request.output else None,
        "best": None
        if best is None
        else {"parameters": best.point, metric: sense * (best.score or 0.0)}
        | {
            m: best.runs[0].get(m)
            for m in ("slip_ratio", "torque_nm", "torque_ratio", "lateral_ratio")
            if best.runs and m in best.runs[0]
        },
        "on_edge": outcome.edges(request.space),
    }


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
