"""Pictures of the physics studies (matplotlib, Agg: no display needed): a thesis run's
time series in both worlds, and the friction study."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from snakebot.plots.files import save_figure
from snakebot.plots.video import DEFAULT_SIZE, check_video_path, write_video
from snakebot.workflows.thesis import ThesisResult, ThesisRun, run_thesis

WORLD_STYLE = {"kinematic": ("tab:blue", "-"), "mujoco": ("tab:orange", "-")}


def thesis_study(
    runs: Sequence[ThesisRun],
    out_dir: Path,
    *,
    mu: float | None = None,
    video: Path | None = None,
    video_size: tuple[int, int] = DEFAULT_SIZE,
    say: Callable[[str], Any] = print,
    started: Callable[[int, ThesisRun], None] = lambda i, run: None,
    finished: Callable[[dict[str, Any]], None] = lambda summary: None,
) -> list[dict[str, Any]]:
    """Play each of ``runs`` in both worlds (``mu``: the physics world's wheel-floor
    friction), draw it into ``out_dir``/NAME.png and, with ``video``, film it (FILE for
    one run; for several, FILE's name with -NAME added); the runs' summaries, with the
    files written. ``started(i, run)`` comes before the i-th run (from 1), ``finished``
    with its summary."""
    if video is not None:
        check_video_path(video)
    out_dir.mkdir(parents=True, exist_ok=True)
    summaries = []
    for i, run in enumerate(runs, start=1):
        started(i, run)
        result = run_thesis(run, mu=mu)
        summary = result.summary()
        summary["png"] = str(plot_thesis_run(result, out_dir / f"{run.name}.png"))
        if video is not None:
            name = video if len(runs) == 1 else video.with_stem(f"{video.stem}-{run.name}")
            motions = {world: p.emulated for world, p in result.worlds.items()}
            title = f"thesis run {run.name}"
            path = write_video(name, result.robot, motions, title, size=video_size, say=say)
            summary["video"] = str(path)
        summaries.append(summary)
        finished(summary)
    return summaries


GRID_COLUMNS = 4
"""Panels per row of a thesis run's figure: a grid a laptop screen shows whole."""


def plot_thesis_run(result: ThesisResult, out: str | Path) -> Path:
    """PNG of :func:`thesis_figure`."""
    return save_figure(thesis_figure(result), out, 90)


def thesis_figure(result: ThesisResult) -> Figure:
    """x, y, theta and each joint against t, as the thesis's figures show them, in a grid
    of :data:`GRID_COLUMNS` panels a row, with both worlds overlaid and the model's ideal
    path (field runs) dashed; one legend for all, below the panels."""
    robot = result.robot
    names = ["x", "y", "theta", *(j.name for j in robot.joints)]
    rows = math.ceil(len(names) / GRID_COLUMNS)
    fig = Figure(figsize=(3.3 * GRID_COLUMNS, 2.6 * rows + 0.9), layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.subplots(rows, GRID_COLUMNS, sharex=True, squeeze=False).ravel()
    for ax in grid[len(names) :]:
        ax.set_visible(False)
    axes = grid[: len(names)]
    for world, prediction in result.worlds.items():
        rec = prediction.emulated
        color, style = WORLD_STYLE.get(world, ("tab:green", "-"))
        series = np.hstack([rec.pose, rec.phi])
        for k, ax in enumerate(axes):
            ax.plot(rec.t, series[:, k], style, color=color, label=world)
    if result.model_q is not None:
        for k, ax in enumerate(axes):
            ax.plot(result.t, result.model_q[:, k], "--", color="gray", label="model (ideal)")
    for k, (ax, name) in enumerate(zip(axes, names, strict=True)):
        ax.set_title(name, fontsize="medium")
        if k + GRID_COLUMNS >= len(names):  # the lowest panel of its column
            ax.set_xlabel("t (s)")
            ax.xaxis.set_tick_params(labelbottom=True)
        ax.set_ylabel(f"{name} ({robot.length_unit})" if name in ("x", "y") else f"{name} (rad)")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=len(labels), fontsize="small")
    fig.suptitle(
        f"thesis run {result.run.name} on {robot.name}: kinematic and MuJoCo worlds "
        "(x, y: the body's reference point in the start frame; angles counter-clockwise)",
        fontsize="medium",
    )
    return fig


def plot_friction(study: dict[str, Any], out: str | Path) -> Path:
    """PNG: distance per cycle in the physics world against the friction coefficient,
    with the quasi-static model's (on the table's joints and on the physics world's)
    beside it, the kinematic world's at the robot's friction, and the wheels' sideways
    slide."""
    fig = Figure(figsize=(10, 4), layout="constrained")
    FigureCanvasAgg(fig)
    ax_d, ax_s = fig.subplots(1, 2)
    mu = [p["mu"] for p in study["points"]]
    ax_d.semilogx(mu, [p["distance_per_cycle"] for p in study["points"]], "o-", label="MuJoCo")
    ax_d.semilogx(
        mu,
        [p["kinematic_distance_per_cycle"] for p in study["points"]],
        "s--",
        label="quasi-static on the table's joints, same mu",
    )
    ax_d.semilogx(
        mu,
        [p["kinematic_on_physics_joints_per_cycle"] for p in study["points"]],
        "^:",
        label="quasi-static on MuJoCo's joint motion",
    )
    f = study["friction"]
    for key, label, style in (
        ("kinematic", f"kinematic world, robot's mu = {f['lateral']:g}", "--"),
        ("kinematic_free_wheels", "quasi-static on the table's joints, free wheels", ":"),
    ):
        ax_d.axhline(study[key]["distance_per_cycle"], linestyle=style, color="gray", label=label)
    ax_d.set_xlabel("wheel-floor friction coefficient mu")
    ax_d.set_ylabel(f"distance per cycle ({study['units']})")
    ax_d.set_title(f"{study['gait']} on {study['robot']}")
    ax_d.legend(fontsize="small")
    ax_d.grid(alpha=0.3, which="both")
    ax_s.loglog(mu, [max(p["slip_distance_per_cycle"], 1e-12) for p in study["points"]], "o-")
    ax_s.set_xlabel("wheel-floor friction coefficient mu")
    ax_s.set_ylabel(f"sideways slide per cycle, all wheels ({study['units']})")
    ax_s.set_title("how far the wheels slid sideways")
    ax_s.grid(alpha=0.3, which="both")
    out = save_figure(fig, out, 90)
    return out
