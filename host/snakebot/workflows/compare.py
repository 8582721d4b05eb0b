"""A recorded run (``snakebot monitor --csv`` or ``--mcap``) lined up against the gait's
prediction: the joint angles the table asks for at each moment (ticks to angles through
the robot's calibration, linear between frames, as the controller plays them) and, when
the run carries an external pose (columns ``pose_x``, ``pose_y`` in metres and
``pose_theta`` in radians, e.g. from motion capture), the body pose the table's motion
integrates to. Errors are reported per joint in degrees.

A run that records the controller's frame (``monitor --csv`` column ``frame``, the MCAP
records' ``controller.play_frame``) is lined up by it: each sample's moment in the gait is
its frame's start, plus the host time since that frame was first seen (at most one frame
period), so a host that stalled cannot shift the rest of the run. When the run also
records the goals the controller sent (column ``goal``), each moment is refined to where
the table's goals equal them (:func:`goal_clock`): the goals are read with the positions,
the frame a READ earlier. Without it the run's
start is found by cross-correlating its first joint with the prediction and the host's
clock is trusted. Gaps between samples (several intervals long) and stalls (the frame not
advancing while the host's clock runs) are reported; a pose that is not a number is
refused."""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from snakebot.errors import InputError
from snakebot.formats.gaittable import GaitTable
from snakebot.link.controller.mcap_log import TOPIC as TELEMETRY_TOPIC
from snakebot.model.compare import JointTrack, best_lag, joint_names, table_angles
from snakebot.model.robots.model import Robot
from snakebot.userfiles import UnreadableInput, read_bounded
from snakebot.workflows.predict import predict_table

RUN_MAX = 256 * 1024 * 1024
"""The largest run file read."""

POSE_COLUMNS = ("pose_x", "pose_y", "pose_theta")


class CompareError(InputError):
    """A run or gait that cannot be compared (exit 2)."""


@dataclass(frozen=True)
class Run:
    """A recording: sample times (s), servo IDs, position ticks per sample and servo, and
    the external pose per sample (None without one)."""

    t: np.ndarray
    ids: tuple[int, ...]
    ticks: np.ndarray  # (samples, servos)
    pose: np.ndarray | None  # (samples, 3): x, y (m), theta (rad)
    frames: np.ndarray | None = None  # the controller's Play Frame per sample, if recorded
    goals: np.ndarray | None = None  # the goal ticks it last sent, per sample and servo


def _read(path: Path) -> bytes:
    try:
        return read_bounded(path, RUN_MAX, "recorded run")
    except UnreadableInput as exc:
        raise CompareError(str(exc)) from None
    except OSError as exc:
        raise CompareError(f"cannot read the run {path}: {exc.strerror or exc}") from None


def _rows_from_csv(path: Path, data: bytes) -> list[dict[str, Any]]:
    try:
        rows = list(csv.DictReader(data.decode("utf-8").splitlines()))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise CompareError(
            f"{path} is not a CSV file ({exc}): give a run the monitor recorded as CSV"
        ) from None
    missing = {"t", "id", "position"} - set(rows[0] if rows else {})
    if missing:
        raise CompareError(
            f"{path} has no column {', '.join(sorted(missing))}: give a run the monitor "
            "recorded as CSV"
        )
    return rows


def _rows_from_mcap(path: Path, data: bytes) -> list[dict[str, Any]]:
    try:
        from mcap.exceptions import EndOfFile
        from mcap.records import Channel, Message
        from mcap.stream_reader import StreamReader
    except ImportError:
        raise CompareError(
            "reading MCAP runs needs the mcap package: pip install 'snakebot[record]'"
        ) from None
    import io

    rows: list[dict[str, Any]] = []
    try:
        # Read as a stream, record by record: a recording cut by a kill (no index, no
        # footer) gives every message of its finished chunks.
        messages = []
        telemetry: set[int] = set()  # the telemetry's channel (the live topics beside it)
        try:
            for item in StreamReader(io.BytesIO(data)).records:
                if isinstance(item, Channel) and item.topic == TELEMETRY_TOPIC:
                    telemetry.add(item.id)
                elif isinstance(item, Message) and item.channel_id in telemetry:
                    messages.append(item)
        except EndOfFile:
            pass
        except Exception:  # cut inside a record: keep the messages before it, if any
            if not messages:
                raise
        for message in messages:
            record = json.loads(message.data)
            extra = {k: record[k] for k in POSE_COLUMNS if k in record}
            frame = (record.get("controller") or {}).get("play_frame")
            if frame is not None:
                extra["frame"] = frame
            for servo in record["servos"]:
                rows.append({"t": record["t"], **servo, **extra})
    except (KeyError, ValueError, TypeError) as exc:
        raise CompareError(f"{path} does not hold monitor records ({exc})") from None
    except Exception as exc:  # the mcap reader raises its own errors for damaged files
        raise CompareError(f"{path} is not a readable MCAP file ({exc})") from None
    return rows


def load_run(path: str | Path) -> Run:
    """The run at ``path`` (MCAP by its magic, else CSV), one row per servo per sample."""
    path = Path(path)
    data = _read(path)
    rows = _rows_from_mcap(path, data) if data[:5] == b"\x89MCAP" else _rows_from_csv(path, data)
    try:
        times = sorted({float(r["t"]) for r in rows})
        ids = tuple(sorted({int(r["id"]) for r in rows}))
        index = {t: i for i, t in enumerate(times)}
        ticks = np.full((len(times), len(ids)), np.nan)
        col = {i: k for k, i in enumerate(ids)}
        has_pose = all(r.get(c) not in (None, "") for r in rows for c in POSE_COLUMNS)
        pose = np.full((len(times), 3), np.nan) if has_pose and rows else None
        has_frame = bool(rows) and all(r.get("frame") not in (None, "") for r in rows)
        frames = np.zeros(len(times)) if has_frame else None
        has_goal = has_frame and all(r.get("goal") not in (None, "") for r in rows)
        goals = np.full(ticks.shape, np.nan) if has_goal else None
        for r in rows:
            n = index[float(r["t"])]
            ticks[n, col[int(r["id"])]] = float(r["position"])
            if pose is not None:
                pose[n] = [float(r[c]) for c in POSE_COLUMNS]
            if frames is not None:
                frames[n] = int(r["frame"])
            if goals is not None:
                goals[n, col[int(r["id"])]] = float(r["goal"])
    except (ValueError, KeyError, TypeError) as exc:
        raise CompareError(f"{path}: a row has a value that is not a number ({exc})") from None
    if pose is not None and not np.isfinite(pose).all():
        n = int(np.flatnonzero(~np.isfinite(pose).all(axis=1))[0])
        raise CompareError(
            f"{path}: the pose at t = {times[n]:g} s is not a number ({pose[n].tolist()}): "
            "drop the samples the tracker lost, or the pose columns"
        )
    if len(times) < 3:
        raise CompareError(f"{path} holds {len(times)} samples: record a longer run")
    keep = ~np.isnan(ticks).any(axis=1)  # samples where a servo was missing are dropped
    return Run(
        np.array(times)[keep],
        ids,
        ticks[keep],
        None if pose is None else pose[keep],
        None if frames is None else frames[keep],
        None if goals is None else goals[keep],
    )


GAP_INTERVALS = 4.0
"""A pause between samples this many times the run's median interval is a gap."""


def find_gaps(t: np.ndarray) -> list[tuple[float, float]]:
    """(time from the run's start, length) of each gap between samples (GAP_INTERVALS)."""
    steps = np.diff(t)
    if len(steps) == 0:
        return []
    limit = GAP_INTERVALS * float(np.median(steps))
    return [(float(t[k] - t[0]), float(steps[k])) for k in np.flatnonzero(steps > limit)]


def controller_clock(t: np.ndarray, frames: np.ndarray, table: GaitTable) -> np.ndarray:
    """Each sample's moment in the gait by the controller's frame (see the module note):
    frames unwrapped over a loop's passes, each sample at its frame's start plus the host
    time since the frame was first seen, capped at one frame period."""
    period = table.frame_period_ms / 1000.0
    unwrapped = _unwrap(frames, table)
    clock = np.empty(len(t))
    seen = t[0]
    for k in range(len(t)):
        if k == 0 or unwrapped[k] != unwrapped[k - 1]:
            seen = t[k]
        clock[k] = unwrapped[k] * period + min(t[k] - seen, period)
    return clock


GOAL_MATCH_TICKS = 1.0
"""The largest difference (ticks, any joint) between a sample's recorded goals and the
table's at the moment found for it: the controller rounds its goals to whole ticks."""

GOAL_STEP_S = 0.001
"""The resolution of the moments tried when lining a sample up by its goals."""

GOAL_WINDOW_S = 2.0
"""The longest stretch of the gait searched for one sample's goals."""


def goal_clock(
    clock: np.ndarray, frames: np.ndarray, goals: np.ndarray, table: GaitTable
) -> tuple[np.ndarray, int]:
    """Each sample's moment in the gait refined by the goals the controller last sent,
    and how many samples matched. The goals come in the same READ as the positions; the
    frame comes in the READ before it, so on a busy host the frame is older than the
    positions. A sample's moment lies between its frame's start and the end of the next
    sample's frame (read after it), at most GOAL_WINDOW_S on; the one there whose table
    goals (linear between frames, as played) equal the recorded goals within
    GOAL_MATCH_TICKS, nearest the frame's moment, is taken. A sample whose goals match
    nowhere (a steering offset, a speed scale) keeps the frame's moment."""
    period = table.frame_period_ms / 1000.0
    rows = table.frames.astype(float)
    if table.loop:
        rows = np.vstack([rows, rows[:1]])
    grid = np.arange(len(rows)) * period
    span = period * table.frame_count

    def goals_at(tt: np.ndarray) -> np.ndarray:
        tt = np.mod(tt, span) if table.loop else tt
        return np.column_stack([np.interp(tt, grid, rows[:, j]) for j in range(rows.shape[1])])

    starts = _unwrap(frames, table) * period
    out = clock.copy()
    matched = 0
    for k in range(len(clock)):
        end = starts[k + 1] + period if k + 1 < len(clock) else math.inf
        tried = np.arange(starts[k], min(end, starts[k] + GOAL_WINDOW_S), GOAL_STEP_S)
        fits = np.abs(goals_at(tried) - goals[k]).max(axis=1) <= GOAL_MATCH_TICKS
        if fits.any():
            near = tried[fits]
            out[k] = float(near[np.argmin(np.abs(near - clock[k]))])
            matched += 1
    return out, matched


def _unwrap(frames: np.ndarray, table: GaitTable) -> np.ndarray:
    """Frame numbers counted on over a loop's passes (a frame lower than the one before
    starts a new pass)."""
    passes = np.concatenate([[0], np.cumsum(np.diff(frames) < 0)])
    return frames + passes * table.frame_count


def find_stalls(t: np.ndarray, frames: np.ndarray, table: GaitTable) -> list[tuple[float, float]]:
    """(time from the run's start, length) of each stall: the host's clock ran on more
    than two frame periods beyond the frames the controller played meanwhile (the
    controller, or the emulator under it, stood still)."""
    period = table.frame_period_ms / 1000.0
    unwrapped = _unwrap(frames, table)
    changes = np.concatenate([[0], np.flatnonzero(np.diff(unwrapped) != 0) + 1])
    out: list[tuple[float, float]] = []
    for a, b in zip(changes[:-1], changes[1:], strict=True):
        excess = float(t[b] - t[a]) - float(unwrapped[b] - unwrapped[a]) * period
        if excess > 2 * period:
            out.append((float(t[a] - t[0]), excess))
    return out


def _pose_at(robot: Robot, table: GaitTable, t: np.ndarray) -> np.ndarray:
    """The body pose the table's motion integrates to at times ``t`` (from its start),
    passes composed for a looping table."""
    intervals = table.frame_count if table.loop else table.frame_count - 1
    traj, _ = predict_table(robot, table, intervals * 8 + 1)
    one = traj.q[:, :3]
    span = float(traj.t[-1])
    passes = np.floor(t / span).astype(int) if table.loop else np.zeros(len(t), int)
    within = t - passes * span if table.loop else np.minimum(t, span)
    x, y, th = (np.interp(within, traj.t, one[:, k]) for k in range(3))
    end = one[-1] - one[0]
    out = np.empty((len(t), 3))
    for i, n in enumerate(passes):
        px = py = pth = 0.0
        for _ in range(n):  # compose whole passes: each moves by `end` in its own frame
            c, s = math.cos(pth), math.sin(pth)
            px, py, pth = px + c * end[0] - s * end[1], py + s * end[0] + c * end[1], pth + end[2]
        c, s = math.cos(pth), math.sin(pth)
        dx, dy = x[i] - one[0, 0], y[i] - one[0, 1]
        out[i] = [px + c * dx - s * dy, py + s * dx + c * dy, pth + th[i] - one[0, 2]]
    return out


@dataclass(frozen=True)
class Comparison:
    """The run against the prediction, after alignment."""

    lag_s: float
    joints: JointTrack  # times from the run's first sample
    pose_error: np.ndarray | None  # distance (m) per sample, when the run has a pose
    aligned_by: str = "host clock"  # or "controller frame"
    gaps: tuple[tuple[float, float], ...] = ()  # (at s, length s) between samples
    stalls: tuple[tuple[float, float], ...] = ()  # (at s, length s) the frame stood still

    def summary(self) -> dict[str, Any]:
        t = self.joints.t
        out: dict[str, Any] = {
            "samples": len(t),
            "duration_s": round(float(t[-1] - t[0]), 3),
            "start_in_gait_s": round(self.lag_s, 4),
            "aligned_by": self.aligned_by,
            "gaps": [{"at_s": round(a, 3), "length_s": round(n, 3)} for a, n in self.gaps],
            "stalls": [{"at_s": round(a, 3), "length_s": round(n, 3)} for a, n in self.stalls],
            "joints": self.joints.per_joint(),
        }
        if self.pose_error is not None:
            out["pose"] = {
                "rms_m": round(float(np.sqrt(np.mean(self.pose_error**2))), 4),
                "max_m": round(float(self.pose_error.max()), 4),
                "final_m": round(float(self.pose_error[-1]), 4),
            }
        return out


def compare(run: Run, table: GaitTable, robot: Robot) -> Comparison:
    """Line ``run`` up against ``table`` played on ``robot``."""
    missing = [i for i in table.joint_ids if i not in run.ids]
    if missing:
        raise CompareError(
            f"the run has no servo {', '.join(map(str, missing))} of the gait's joints "
            f"{', '.join(map(str, table.joint_ids))}: give the run of this gait"
        )
    cols = [run.ids.index(i) for i in table.joint_ids]
    measured = robot.ticks_to_angles(run.ticks[:, cols])
    t = run.t - run.t[0]
    span = (
        table.frame_period_ms
        / 1000.0
        * (table.frame_count if table.loop else table.frame_count - 1)
    )
    gaps = tuple(find_gaps(run.t))
    stalls: tuple[tuple[float, float], ...] = ()
    if run.frames is not None and np.ptp(run.frames) > 0:
        clock = controller_clock(run.t, run.frames, table)
        stalls = tuple(find_stalls(run.t, run.frames, table))
        aligned_by = "controller frame"
        if run.goals is not None:
            clock, matched = goal_clock(clock, run.frames, run.goals[:, cols], table)
            if matched == len(clock):
                aligned_by = "controller goals"
            elif matched:
                aligned_by = (
                    f"controller goals ({matched} of {len(clock)} samples, the rest by frame)"
                )
        lag = float(clock[0])
        gait_t = clock  # the moment in the gait of each sample, by the controller
    else:
        lag = best_lag(t, measured[:, 0], lambda tt: table_angles(robot, table, tt)[:, 0], span)
        gait_t = t + lag
        aligned_by = "host clock"
    predicted = table_angles(robot, table, gait_t)
    pose_error = None
    if run.pose is not None:
        pred = _pose_at(robot, table, gait_t)
        ref = _pose_at(robot, table, np.array([lag]))[0]
        # the run's pose is where the robot was; the prediction's is relative to its start
        c, s = math.cos(run.pose[0, 2] - ref[2]), math.sin(run.pose[0, 2] - ref[2])
        dx, dy = pred[:, 0] - ref[0], pred[:, 1] - ref[1]
        px = run.pose[0, 0] + c * dx - s * dy
        py = run.pose[0, 1] + s * dx + c * dy
        pose_error = np.hypot(run.pose[:, 0] - px, run.pose[:, 1] - py)
    return Comparison(
        lag,
        JointTrack(t, joint_names(robot), measured, predicted),
        pose_error,
        aligned_by,
        gaps,
        stalls,
    )
