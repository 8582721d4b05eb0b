"""Pictures of gaits (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from snakebot.formats.gaittable import GaitTable
from snakebot.model.robots import TICKS_PER_RAD
from snakebot.plots.files import save_figure


def joint_angles(table: GaitTable) -> tuple[np.ndarray, np.ndarray, str]:
    """Frame times (s) and joint angles in degrees (ticks if the metadata lacks the
    joints' zero ticks and signs); a loop gets frame 0 again at its end."""
    ticks = table.frames.astype(float)
    times = np.arange(len(ticks)) * table.frame_period_ms / 1000.0
    if table.loop:
        ticks = np.vstack([ticks, ticks[:1]])
        times = np.append(times, len(table.frames) * table.frame_period_ms / 1000.0)
    joints = table.metadata.get("joints")
    if not joints or len(joints) != table.joint_count:
        return times, ticks, "goal position (ticks)"
    zero = np.array([j["zero_tick"] for j in joints], dtype=float)
    sign = np.array([j["sign"] for j in joints], dtype=float)
    return times, np.degrees((ticks - zero) / (sign * TICKS_PER_RAD)), "joint angle (deg)"


def _pose_series(ax: Any, meta: dict[str, Any]) -> None:
    """x, y (left axis) and theta (right axis) of the predicted body against time, as the
    thesis's simulation figures show them."""
    for key, style, text in (("path", "-", "continuous"), ("table_path", "--", "table")):
        if key not in meta or not meta[key].get("t"):
            continue
        p = meta[key]
        ax.plot(p["t"], p["x"], style, color="tab:blue", label=f"x ({text})")
        ax.plot(p["t"], p["y"], style, color="tab:orange", label=f"y ({text})")
    turn = ax.twinx()
    for key, style in (("path", "-"), ("table_path", "--")):
        if key in meta and meta[key].get("t"):
            turn.plot(meta[key]["t"], meta[key]["theta"], style, color="tab:green")
    turn.set_ylabel("theta (rad, green)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("x, y")
    ax.set_title("predicted body pose against time (start frame)")
    ax.legend(fontsize="small")
    ax.grid(alpha=0.3)


def plot_gait(table: GaitTable, out: str | Path) -> Path:
    """Write a PNG: joint angles over time, and, when the metadata has the predicted
    body motion, x, y, theta over time and the body's path."""
    meta: dict[str, Any] = table.metadata
    has_path = "path" in meta
    fig = Figure(figsize=(16 if has_path else 7, 4.5), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, 3 if has_path else 1, squeeze=False)[0]
    times, values, label = joint_angles(table)
    names = [j.get("name", f"joint {i + 1}") for i, j in enumerate(meta.get("joints", []))]
    for j in range(values.shape[1]):
        name = names[j] if j < len(names) else f"joint {j + 1}"
        axes[0].plot(
            times, values[:, j], marker=".", markersize=3, label=f"{name} (ID {table.joint_ids[j]})"
        )
    axes[0].set_xlabel("time (s)")
    axes[0].set_ylabel(label)
    title = f"{meta.get('gait', 'gait')} on {meta.get('robot', '?')}"
    axes[0].set_title(
        f"{title}: {table.frame_count} frames every {table.frame_period_ms} ms"
        + (", loop" if table.loop else "")
    )
    axes[0].legend(fontsize="small")
    axes[0].grid(alpha=0.3)
    if has_path:
        _pose_series(axes[1], meta)
        ax = axes[2]
        for key, style, text in (
            ("path", "-", "continuous gait"),
            ("table_path", "--", "table as written"),
        ):
            if key in meta:
                ax.plot(meta[key]["x"], meta[key]["y"], style, label=text)
        p = meta["path"]
        ax.plot(p["x"][:1], p["y"][:1], "o", color="black", label="start")
        if p["theta"]:  # an arrow along the final heading, a tenth of the path's extent
            size = 0.1 * max(np.ptp(p["x"]), np.ptp(p["y"]), 1e-9)
            end = p["theta"][-1]
            ax.annotate(
                "",
                xy=(p["x"][-1] + size * math.cos(end), p["y"][-1] + size * math.sin(end)),
                xytext=(p["x"][-1], p["y"][-1]),
                arrowprops={"arrowstyle": "->"},
            )
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        ax.set_title("predicted body path (reference point)")
        ax.legend(fontsize="small")
        ax.grid(alpha=0.3)
    out = save_figure(fig, out, 100)
    return out
