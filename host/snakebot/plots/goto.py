"""The closed loop's plot: the body's path, the poses read after each segment, the
target."""

from __future__ import annotations

import math
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from snakebot.model.plan.planner import body_length
from snakebot.plots.files import save_figure
from snakebot.workflows.goto import GotoResult

ARROW_BODIES = 0.1
"""Heading arrows a tenth of a body length long."""


def plot_goto(result: GotoResult, out: str | Path) -> Path:
    """Write a PNG of the run; returns its path."""
    fig = Figure(figsize=(7, 6), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    q = result.path.q
    ax.plot(q[:, 0], q[:, 1], "-", lw=1, label="reference point (world)")
    reads = [s["pose"] for s in result.segments]
    ax.plot([p["x"] for p in reads], [p["y"] for p in reads], "o", ms=4, label="pose read")
    for pose, style, text in ((result.target, "r", "target"), (result.final, "k", "reached")):
        ax.quiver(
            pose[0],
            pose[1],
            math.cos(pose[2]),
            math.sin(pose[2]),
            color=style,
            label=text,
            angles="xy",
            scale_units="xy",
            scale=1.0 / (ARROW_BODIES * body_length(result.robot)),
        )
    d, h = result.error
    unit = result.robot.length_unit
    ax.set_title(
        f"{result.robot.name} to the target in closed loop ({result.world}): error {d:.3g} "
        f"{unit}, {math.degrees(h):.2f} deg"
    )
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    if result.robot.length_legend:
        fig.text(0.01, 0.005, result.robot.length_legend, fontsize="x-small")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    path = save_figure(fig, out, 110)
    return path
