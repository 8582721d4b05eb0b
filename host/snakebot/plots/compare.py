"""The picture of `snakebot compare` (matplotlib, Agg): each joint recorded and predicted,
and the difference."""

from __future__ import annotations

from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from snakebot.plots.joints import draw_joints
from snakebot.workflows.compare import Comparison


def plot_comparison(c: Comparison, out: str | Path) -> Path:
    """Write two panels: joint angles (recorded solid, predicted dashed) and their error."""
    fig = Figure(figsize=(12, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax_joints, ax_err = fig.subplots(1, 2)
    draw_joints(ax_joints, ax_err, c.joints, "recorded", f"predicted from {c.lag_s:.2f} s")
    ax_joints.set_xlabel("time since the run's first sample (s)")
    out = Path(out)
    fig.savefig(out, dpi=100)
    return out
