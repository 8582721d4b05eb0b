"""The robot seen from above, drawn with matplotlib (no GL at all): the video's fallback
where MuJoCo's offscreen renderer cannot start, and the body's outline the figures use.
Each run is the robot's links and wheels in its own colour, leaving its path behind; the
axes are the world frame in metres when the robot has a ``[physics]`` table (else in the
robot's length units).

    view = TopView(robot, {"kinematic": rec_a, "mujoco": rec_b}, "title", (640, 360))
    frame = view.frame(1.0)   # (360, 640, 3) uint8
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from snakebot.extras import require
from snakebot.model.robots import Robot
from snakebot.plots.motion import Motion, sample_index

COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red")
DPI = 100


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


def length_unit(robot: Robot) -> tuple[float, str]:
    """Metres per robot length unit and the axes' unit: metres where the robot says how
    long its unit is (its [physics] table), else its own units."""
    if robot.physics is not None:
        return robot.physics.unit_m, "m"
    return 1.0, "robot units"


class TopView:
    """Frames of ``runs`` (label -> run, sharing one time axis) seen from above, ``size``
    = (width, height) pixels."""

    def __init__(
        self, robot: Robot, runs: Mapping[str, Motion], title: str, size: tuple[int, int]
    ) -> None:
        require("matplotlib", "drawing a video", params=("video",))
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.robot, self.runs = robot, list(runs.items())
        self.scale, unit = length_unit(robot)
        width, height = size
        fig = Figure(figsize=(width / DPI, height / DPI), dpi=DPI, layout="constrained")
        self.canvas = FigureCanvasAgg(fig)
        ax = fig.subplots()
        everything = []
        for _, rec in self.runs:
            for k in (0, len(rec.t) - 1):
                chain, _ = body_points(robot, rec.pose[k], rec.phi[k])
                everything.append(chain[np.isfinite(chain[:, 0])])
            everything.append(rec.pose[:, :2])
        pts = np.vstack(everything) * self.scale
        span = max(float(np.ptp(pts[:, 0])), float(np.ptp(pts[:, 1])), 1e-9) * 0.55
        span += robot.l * self.scale
        centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        ax.set_xlim(centre[0] - span, centre[0] + span)
        ax.set_ylim(centre[1] - span, centre[1] + span)
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_xlabel(f"x ({unit}, world frame)")
        ax.set_ylabel(f"y ({unit})")
        ax.set_title(title or f"{robot.name} seen from above", fontsize="small")
        self.artists = []
        for i, (label, _) in enumerate(self.runs):
            color = COLORS[i % len(COLORS)]
            (trail,) = ax.plot([], [], "-", color=color, alpha=0.5, lw=1)
            (body,) = ax.plot([], [], "-", color=color, lw=3, label=label)
            (wheel,) = ax.plot([], [], "o", color="black", ms=5)
            self.artists.append((trail, body, wheel))
        self.clock = ax.text(0.02, 0.97, "", transform=ax.transAxes, va="top")
        fig.legend(loc="outside lower center", fontsize="small", ncols=len(self.runs))

    def frame(self, t: float) -> np.ndarray:
        """The picture at time ``t``: (height, width, 3) uint8."""
        s = self.scale
        for (_, rec), (trail, body, wheel) in zip(self.runs, self.artists, strict=True):
            k = sample_index(rec.t, t)
            chain, wheels = body_points(self.robot, rec.pose[k], rec.phi[k])
            trail.set_data(rec.pose[: k + 1, 0] * s, rec.pose[: k + 1, 1] * s)
            body.set_data(chain[:, 0] * s, chain[:, 1] * s)
            wheel.set_data(wheels[:, 0] * s, wheels[:, 1] * s)
        self.clock.set_text(f"t = {t:5.2f} s")
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[:, :, :3].copy()

    def close(self) -> None:
        """Nothing to free (the figure goes with the view); the renderers' interface."""
