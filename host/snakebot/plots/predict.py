"""The picture of a ``snakebot sim predict`` run (matplotlib, Agg: no display needed):
the emulated body path beside the predicted one, and how well the servos tracked."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from snakebot.plots.files import save_figure
from snakebot.plots.joints import draw_joints
from snakebot.workflows.predict import Prediction


def _heading_arrow(ax: Axes, x: float, y: float, theta: float, size: float, color: str) -> None:
    ax.annotate(
        "",
        xy=(x + size * math.cos(theta), y + size * math.sin(theta)),
        xytext=(x, y),
        arrowprops={"arrowstyle": "->", "color": color},
    )


def plot_prediction(result: Prediction, out: str | Path) -> Path:
    """Write a PNG with three panels: body paths, joint angles, joint tracking error."""
    fig = Figure(figsize=(15, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax_path, ax_joints, ax_err = fig.subplots(1, 3)
    em, pr = result.emulated, result.predicted
    servos = "ideal servos" if result.ideal else f"{result.robot.servo_model} servos"

    ax_path.plot(pr.q[:, 0], pr.q[:, 1], "--", color="tab:blue", label="predicted (table)")
    ax_path.plot(
        em.pose[:, 0], em.pose[:, 1], "-", color="tab:orange", label=f"emulated ({servos})"
    )
    ax_path.plot(em.pose[:1, 0], em.pose[:1, 1], "o", color="black", label="start")
    extent = max(
        np.ptp(pr.q[:, 0]), np.ptp(pr.q[:, 1]), np.ptp(em.pose[:, 0]), np.ptp(em.pose[:, 1]), 1e-9
    )
    _heading_arrow(ax_path, pr.q[-1, 0], pr.q[-1, 1], pr.q[-1, 2], 0.1 * extent, "tab:blue")
    _heading_arrow(
        ax_path, em.pose[-1, 0], em.pose[-1, 1], em.pose[-1, 2], 0.1 * extent, "tab:orange"
    )
    ax_path.set_aspect("equal", adjustable="datalim")
    ax_path.set_xlabel("x")
    ax_path.set_ylabel("y")
    ax_path.set_title(f"body path of {result.robot.name} (reference point)")
    ax_path.legend(fontsize="small")
    ax_path.grid(alpha=0.3)

    draw_joints(ax_joints, ax_err, result.joints, "servo", "table")
    out = save_figure(fig, out, 100)
    return out
