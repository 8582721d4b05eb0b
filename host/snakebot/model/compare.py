"""One comparison of a run with its prediction, shared by the demo, ``snakebot compare``
and ``snakebot sim predict``: joint angles measured beside the angles predicted for the
same instants (:class:`JointTrack`, with its error per joint), what a gait table asks for
at any instant (:func:`table_angles`), the start offset that lines a run up with a table
(:func:`best_lag`), and body motion in the frame of its start (:func:`relative`,
:func:`motion`). Pure computation: the callers bring the samples."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snakebot.formats.gaittable import GaitTable
from snakebot.model.robots.model import Robot


@dataclass(frozen=True)
class JointTrack:
    """Joint angles (rad) measured and predicted at the same times ``t`` (s), one column
    per joint."""

    t: np.ndarray
    names: tuple[str, ...]
    measured: np.ndarray = field(repr=False)
    predicted: np.ndarray = field(repr=False)

    @property
    def error(self) -> np.ndarray:
        """Measured minus predicted (rad), per sample and joint."""
        return self.measured - self.predicted

    @property
    def max_rad(self) -> float:
        """The largest error over every joint and sample."""
        return float(np.abs(self.error).max())

    @property
    def rms_rad(self) -> float:
        """The root mean square of the error over every joint and sample."""
        return float(np.sqrt(np.mean(self.error**2)))

    def per_joint(self) -> list[dict[str, Any]]:
        """Each joint's error in degrees: ``joint``, ``rms_deg``, ``max_deg``."""
        err = np.degrees(self.error)
        return [
            {
                "joint": name,
                "rms_deg": round(float(np.sqrt(np.mean(err[:, j] ** 2))), 3),
                "max_deg": round(float(np.abs(err[:, j]).max()), 3),
            }
            for j, name in enumerate(self.names)
        ]


def joint_names(robot: Robot) -> tuple[str, ...]:
    return tuple(j.name for j in robot.joints)


def table_angles(robot: Robot, table: GaitTable, t: np.ndarray) -> np.ndarray:
    """The joint angles (rad) the table asks for at times ``t`` (s) from its start: linear
    between frames; a loop wraps, a single pass holds its last frame."""
    frames = robot.ticks_to_angles(table.frames)
    period = table.frame_period_ms / 1000.0
    if table.loop:
        frames = np.vstack([frames, frames[:1]])
        span = period * table.frame_count
        t = np.mod(t, span)
    grid = np.arange(len(frames)) * period
    return np.column_stack([np.interp(t, grid, frames[:, j]) for j in range(frames.shape[1])])


def best_lag(
    t: np.ndarray, measured: np.ndarray, predicted: Callable[[np.ndarray], np.ndarray], span: float
) -> float:
    """The start time in the prediction (0..span s) that makes ``predicted(t + lag)`` best
    match ``measured`` (normalised cross-correlation of the zero-mean signals)."""
    dt = float(np.median(np.diff(t)))
    lags = np.arange(0.0, max(span, dt), dt / 2)
    m = measured - measured.mean()
    scores = []
    for lag in lags:
        p = predicted(t + lag)
        p = p - p.mean()
        denom = math.sqrt(float(m @ m) * float(p @ p)) or 1.0
        scores.append(float(m @ p) / denom)
    return float(lags[int(np.argmax(scores))])


def interp_rows(t: np.ndarray, ts: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``rows`` sampled at ``ts``, interpolated linearly at ``t``, column by column."""
    return np.column_stack([np.interp(t, ts, rows[:, j]) for j in range(rows.shape[1])])


def relative(pose0: Sequence[float] | np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Poses (x, y, theta) in the frame of ``pose0`` (+x along its heading)."""
    c, s = math.cos(pose0[2]), math.sin(pose0[2])
    d = poses[:, :2] - np.asarray(pose0[:2])
    return np.column_stack(
        [c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], poses[:, 2] - pose0[2]]
    )


def motion(q_end: np.ndarray) -> dict[str, float]:
    """A body's motion from the origin to ``q_end`` (x, y, theta): the displacement, its
    length and direction, and the turn."""
    dx, dy, dth = (float(v) for v in q_end[:3])
    return {
        "dx": dx,
        "dy": dy,
        "dtheta": dth,
        "distance": math.hypot(dx, dy),
        "direction_deg": math.degrees(math.atan2(dy, dx)),
        "turn_deg": math.degrees(dth),
    }
