"""Pictures of a search (matplotlib, Agg): a heat map of the score over the first two
varied parameters (the best over the others), or, with a single varied parameter or a
sampled search, distance (or speed) against its cost, the slide (kinematic world) or the
motors' energy (physics world), with the Pareto front."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from snakebot.plots.files import save_figure
from snakebot.workflows.search.search import OBJECTIVES, Outcome, Request

ANGLE_UNITS = {"amplitude": "deg", "omega": "deg/s", "delta": "deg", "offset": "deg"}


def _shown(name: str, values: np.ndarray) -> np.ndarray:
    return np.degrees(values) if name in ANGLE_UNITS else values


def plot_search(outcome: Outcome, request: Request, out: Path) -> Path:
    fig = Figure(figsize=(7, 5.5))
    ax = fig.add_subplot()
    metric, sense = OBJECTIVES[request.objective]
    varied = request.space.varied
    if request.method == "grid" and len(varied) >= 2:
        _heat_map(fig, ax, outcome, request, metric, sense)
    else:
        _pareto(ax, outcome, request)
    ax.set_title(
        f"{request.settings.robot}, {request.settings.world} world: {request.objective}"
        f" ({request.method}, {len(outcome.candidates)} candidates)"
    )
    fig.tight_layout()
    FigureCanvasAgg(fig)
    return save_figure(fig, out, 100)


def _heat_map(
    fig: Figure, ax: Axes, outcome: Outcome, request: Request, metric: str, sense: float
) -> None:
    a, b = request.space.varied[:2]
    xs, ys = a.values(), b.values()
    grid = np.full((len(ys), len(xs)), np.nan)
    for c in outcome.candidates:
        if c.score is None:
            continue
        i = int(np.argmin(np.abs(ys - c.point[b.name])))
        j = int(np.argmin(np.abs(xs - c.point[a.name])))
        value = sense * c.score  # the metric itself, worst over the robustness values
        best = grid[i, j]
        if math.isnan(best) or sense * value > sense * best:
            grid[i, j] = value
    sx, sy = _shown(a.name, xs), _shown(b.name, ys)
    mesh = ax.pcolormesh(sx, sy, np.ma.masked_invalid(grid), shading="nearest", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label=f"{metric} (blank: failed)")
    ax.set_xlabel(f"{a.name} ({ANGLE_UNITS.get(a.name, '')})")
    ax.set_ylabel(f"{b.name} ({ANGLE_UNITS.get(b.name, '')})")


def _pareto(ax: Axes, outcome: Outcome, request: Request) -> None:
    # the trade-off behind every objective: how far (or how fast) against what it costs
    metric = "speed" if request.objective == "speed" else "distance_per_cycle"
    other = "electrical_j" if request.settings.world == "mujoco" else "slip_per_cycle"
    ok = [r for r in outcome.rows if r["status"] == "ok"]
    x = np.array([float(r[other]) for r in ok])
    y = np.array([float(r[metric]) for r in ok])
    ax.scatter(x, y, s=12, alpha=0.6, label="runs")
    front = _front(x, y)
    ax.plot(
        x[front], y[front], "r.-", label="Pareto front (less " + other + ", more " + metric + ")"
    )
    ax.set_xlabel(other)
    ax.set_ylabel(metric)
    ax.legend()


def _front(cost: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """Indices of the points no other point beats on both (less cost, more gain), by cost."""
    order = np.lexsort((-gain, cost))
    front, best = [], -math.inf
    for i in order:
        if gain[i] > best:
            front.append(i)
            best = gain[i]
    return np.array(front, dtype=int)
