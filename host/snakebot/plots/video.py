"""Videos of a run seen from above (matplotlib animation: no display, no GPU): the
robot's links and wheels moving over the floor, one or more worlds overlaid, each
leaving its path behind. GIF through Pillow (a matplotlib dependency); MP4 when ffmpeg is
on PATH.

    write_video("run.gif", robot, {"kinematic": rec_a, "mujoco": rec_b})
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple, Protocol

import numpy as np

from snakebot.errors import InputError
from snakebot.extras import require
from snakebot.model.robots import Robot

if TYPE_CHECKING:  # matplotlib is the `plot` extra: imported when a video is written
    from matplotlib.animation import AbstractMovieWriter

FPS = 20
MAX_FRAMES = 300
"""Longer runs are shown faster (the video's clock says how much)."""

COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red")


class VideoError(InputError):
    """A video that cannot be written as asked."""


class Motion(Protocol):
    """What a video shows of a run (a world's record has it): sample times, body poses
    (x, y, theta) and joint angles."""

    t: np.ndarray
    pose: np.ndarray
    phi: np.ndarray


class StateMotion(NamedTuple):
    """A motion given as arrays, e.g. a prediction's states ``q`` split up."""

    t: np.ndarray
    pose: np.ndarray
    phi: np.ndarray

    @classmethod
    def of_states(cls, t: np.ndarray, q: np.ndarray) -> StateMotion:
        return cls(t, q[:, :3], q[:, 3:])


def body_points(robot: Robot, pose: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The robot drawn from above at one state: a polyline through its links (snake: the
    chain from the free end of link 1; trident: each arm from the base's centre through
    its corner, NaN-separated) and its wheels' centres (link middles, arm ends)."""
    x, y, theta = (float(v) for v in pose)
    if robot.kind == "snake":
        headings = theta + np.concatenate([[0.0], np.cumsum(phi)])
        steps = 2 * robot.l * np.column_stack([np.cos(headings), np.sin(headings)])
        joints = np.vstack([[x, y], [x, y] + np.cumsum(steps, axis=0)])
        return joints, 0.5 * (joints[:-1] + joints[1:])
    lines, wheels = [], []
    for alpha, p in zip(robot.alphas, phi, strict=True):
        corner = np.array([x, y]) + robot.r * np.array(
            [math.cos(theta + alpha), math.sin(theta + alpha)]
        )
        end = corner + robot.l * np.array(
            [math.cos(theta + alpha + p), math.sin(theta + alpha + p)]
        )
        lines += [[x, y], corner, end, [np.nan, np.nan]]
        wheels.append(end)
    return np.array(lines), np.array(wheels)


def _writer(path: Path) -> AbstractMovieWriter:
    require("matplotlib", "--video")
    from matplotlib import animation

    suffix = path.suffix.lower()
    if suffix == ".gif":
        return animation.PillowWriter(fps=FPS)
    if suffix == ".mp4":
        if not animation.FFMpegWriter.isAvailable():
            raise VideoError(
                f"{path}: MP4 needs ffmpeg on PATH (apt install ffmpeg); or give a .gif name"
            )
        return animation.FFMpegWriter(fps=FPS)
    raise VideoError(f"{path}: the video must be a .gif or an .mp4 file")


def check_video_path(path: Path) -> Path:
    """``path`` if a video can be written there (raises VideoError otherwise), before any
    long run starts."""
    _writer(path)
    if not path.parent.is_dir():
        raise VideoError(f"{path}: the directory {path.parent} does not exist")
    return path


def write_video(
    path: str | Path, robot: Robot, records: Mapping[str, Motion], title: str = ""
) -> Path:
    """Write the runs in ``records`` (label -> record, sharing one time axis) overlaid,
    seen from above, to ``path`` (.gif or .mp4)."""
    path = Path(path)
    writer = _writer(path)
    items = list(records.items())
    if not items or not len(items[0][1].t):
        raise VideoError("nothing to show: the run recorded no samples")
    t = items[0][1].t
    duration = float(t[-1])
    frames = max(2, min(MAX_FRAMES, int(duration * FPS) + 1))
    times = np.linspace(0.0, duration, frames)
    speedup = duration / (frames / FPS) if frames > 1 else 1.0

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5, 5), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    everything = []
    for _, rec in items:
        for k in (0, len(rec.t) - 1):
            chain, wheels = body_points(robot, rec.pose[k], rec.phi[k])
            everything.append(chain[np.isfinite(chain[:, 0])])
        everything.append(rec.pose[:, :2])
    pts = np.vstack(everything)
    span = max(float(np.ptp(pts[:, 0])), float(np.ptp(pts[:, 1])), 1e-9) * 0.55 + robot.l
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    ax.set_xlim(centre[0] - span, centre[0] + span)
    ax.set_ylim(centre[1] - span, centre[1] + span)
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.set_xlabel("x (robot units)")
    ax.set_ylabel("y (robot units)")
    ax.set_title(title or f"{robot.name} seen from above")
    artists = []
    for i, (label, _) in enumerate(items):
        color = COLORS[i % len(COLORS)]
        (trail,) = ax.plot([], [], "-", color=color, alpha=0.5, lw=1)
        (body,) = ax.plot([], [], "-", color=color, lw=3, label=label)
        (wheel,) = ax.plot([], [], "o", color="black", ms=5)
        artists.append((trail, body, wheel))
    clock = ax.text(0.02, 0.97, "", transform=ax.transAxes, va="top")
    ax.legend(loc="upper right", fontsize="small")

    with writer.saving(fig, str(path), dpi=72):
        for now in times:
            for (_, rec), (trail, body, wheel) in zip(items, artists, strict=True):
                k = min(int(np.searchsorted(rec.t, now, side="right")) - 1, len(rec.t) - 1)
                k = max(k, 0)
                chain, wheels = body_points(robot, rec.pose[k], rec.phi[k])
                trail.set_data(rec.pose[: k + 1, 0], rec.pose[: k + 1, 1])
                body.set_data(chain[:, 0], chain[:, 1])
                wheel.set_data(wheels[:, 0], wheels[:, 1])
            clock.set_text(f"t = {now:5.2f} s" + (f"  ({speedup:.1f}x)" if speedup > 1.05 else ""))
            writer.grab_frame()
    return path
