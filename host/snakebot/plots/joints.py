"""The one joints figure: each joint's measured and predicted angle on one axis, and their
difference on another, for the demo, ``snakebot compare`` and ``sim predict``."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes

from snakebot.model.compare import JointTrack

COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


def draw_joints(
    ax_joints: Axes,
    ax_error: Axes | None,
    track: JointTrack,
    measured: str,
    predicted: str,
    t0: float = 0.0,
) -> None:
    """Measured angles solid and predicted dashed (degrees) against time from ``t0``; the
    error per joint on ``ax_error`` when given. ``measured``/``predicted`` name the two
    sources in the legend and the titles."""
    t = track.t - t0
    for j, name in enumerate(track.names):
        colour = COLOURS[j % len(COLOURS)]
        ax_joints.plot(
            t,
            np.degrees(track.measured[:, j]),
            "-",
            color=colour,
            linewidth=1.5,
            alpha=0.8,
            label=f"{name} {measured}",
        )
        ax_joints.plot(
            t,
            np.degrees(track.predicted[:, j]),
            "--",
            color=colour,
            linewidth=1,
            label=f"{name} {predicted}",
        )
        if ax_error is not None:
            ax_error.plot(t, np.degrees(track.error[:, j]), "-", color=colour, label=name)
    ax_joints.set_xlabel("time (s)")
    ax_joints.set_ylabel("joint angle (deg)")
    ax_joints.set_title(f"joint angles: {measured} (solid), {predicted} (dashed)")
    ax_joints.legend(fontsize="x-small", ncol=2)
    ax_joints.grid(alpha=0.3)
    if ax_error is not None:
        ax_error.set_xlabel("time (s)")
        ax_error.set_ylabel(f"{measured} minus {predicted} (deg)")
        ax_error.set_title("joint error")
        ax_error.legend(fontsize="x-small", ncol=2)
        ax_error.grid(alpha=0.3)
