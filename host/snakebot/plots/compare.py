"""The picture of `snakebot compare` (matplotlib, Agg): each joint recorded and predicted,
and the difference."""

from __future__ import annotations

from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from snakebot.workflows.compare import Comparison


def plot_comparison(c: Comparison, out: str | Path) -> Path:
    """Write two panels: joint angles (recorded solid, predicted dashed) and their error."""
    fig = Figure(figsize=(12, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    ax_joints, ax_err = fig.subplots(1, 2)
    for j, name in enumerate(c.names):
        (line,) = ax_joints.plot(c.t, c.measured_deg[:, j], "-", label=name)
        ax_joints.plot(c.t, c.predicted_deg[:, j], "--", color=line.get_color())
        ax_err.plot(c.t, c.measured_deg[:, j] - c.predicted_deg[:, j], label=name)
    ax_joints.set_title(f"joints: recorded (solid), predicted (dashed, from {c.lag_s:.2f} s)")
    ax_joints.set_xlabel("time (s)")
    ax_joints.set_ylabel("angle (deg)")
    ax_joints.legend(fontsize="x-small", ncol=2)
    ax_joints.grid(alpha=0.3)
    ax_err.set_title("recorded minus predicted")
    ax_err.set_xlabel("time (s)")
    ax_err.set_ylabel("error (deg)")
    ax_err.legend(fontsize="x-small", ncol=2)
    ax_err.grid(alpha=0.3)
    out = Path(out)
    fig.savefig(out, dpi=100)
    return out
