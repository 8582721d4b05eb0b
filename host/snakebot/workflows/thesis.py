"""The thesis's chapter 4 rerun: its trident and 3-link snake simulations, played on the
emulated robot in both worlds.

Each run is what the thesis commanded its simulated joints to do, with its own settings:

* g1, g2, g3: the trident driven along one control vector field with a constant input
  u_i = 1 for 2 s;
* h1, h2, h3: the trident's periodic inputs u_i = -A w sin(w t), u_j = A w cos(w t) on the
  pairs (1, 2), (1, 3), (2, 3) with (A, w) = (0.3, 3), (0.2, 3), (0.25, 2), run for
  2 x 2.5 pi / w: the thesis's simulation cycle, not a whole number of periods;
* serpenoid: the 3-link snake's joints phi_1 = cos(-2 pi^2/3 t + pi^2),
  phi_2 = cos(-2 pi^2/3 t - 2 pi^2), read literally, for 2 x 2.5 pi / w as well.

The thesis computed its trident's joint targets from the world-velocity form of the
model (its simulator script), so the runs use that form. Here the joint path is the
model's (integrated once, ideally), clipped to the joints' limits, and written as a gait
table at the finest frame period the controller holds; the host plays it on the emulated
robot (``snakebot.workflows.predict``), once in the kinematic world and once in the physics
world, and the runs report the model's ideal end state beside both worlds'.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from snakebot.formats.gaittable import GaitTable
from snakebot.formats.gaittable.layout import max_frames
from snakebot.model.gait.common import PREDICT_OPTIONS
from snakebot.model.kinematics import Inputs, integrate_fields
from snakebot.model.robots import Robot, load_robot
from snakebot.sim.physics.select import WORLDS
from snakebot.workflows.predict import Prediction, predict_gait

FRAME_PERIOD_MS = 20
"""The finest frame period used (50 frames a second), longer where a run needs more
frames than the controller holds."""

SERPENOID_OMEGA = 2 * math.pi**2 / 3
"""The thesis's 3-link serpenoid frequency (rad/s)."""


def thesis_cycle(omega: float) -> float:
    """The thesis's simulation time for a periodic input: two of its T = 2.5 pi / w."""
    return 2 * 2.5 * math.pi / omega


@dataclass(frozen=True)
class ThesisRun:
    """One of the thesis's simulations: its name, robot, commanded inputs and duration,
    and what the thesis saw."""

    name: str
    robot: str
    duration_s: float
    observed: str
    inputs: Inputs | None = None  # trident runs: the field inputs (world form)

    def joint_path(self, robot: Robot, t: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """The commanded joint angles at times ``t`` (before clipping) and, for field
        runs, the model's ideal states q(t)."""
        if self.inputs is None:  # the literal serpenoid
            w = SERPENOID_OMEGA
            phi = np.column_stack([np.cos(-w * t + math.pi**2), np.cos(-w * t - 2 * math.pi**2)])
            return phi, None
        traj = integrate_fields(
            robot, self.inputs, float(t[-1]), samples=len(t), options=PREDICT_OPTIONS
        )
        return traj.q[:, 3:], traj.q


def _loop(i: int, j: int, amplitude: float, omega: float) -> Inputs:
    a = [0.0, 0.0, 0.0]
    b = [0.0, 0.0, 0.0]
    a[i] = -amplitude * omega
    b[j] = amplitude * omega
    return Inputs(c=(0.0, 0.0, 0.0), a=tuple(a), b=tuple(b), omega=omega, form="world")


def _direct(i: int) -> Inputs:
    c = [0.0, 0.0, 0.0]
    c[i] = 1.0
    return Inputs(c=tuple(c), form="world")


RUNS: tuple[ThesisRun, ...] = (
    ThesisRun(
        "g1",
        "trident",
        2.0,
        "moves along x with a significant drift in y; the heading turns a little; phi1 "
        "and phi3 start with similar slopes, phi2 near 0, then drift apart",
        _direct(0),
    ),
    ThesisRun(
        "g2",
        "trident",
        2.0,
        "moves in -y instead of +y; small rotation at first; the joints follow the "
        "model up to about 0.5 s",
        _direct(1),
    ),
    ThesisRun(
        "g3",
        "trident",
        2.0,
        "turns as expected with a slight drift in -x and -y; the joints turn slower than "
        "the field asks",
        _direct(2),
    ),
    ThesisRun(
        "h1",
        "trident",
        thesis_cycle(3.0),
        "the joints diverge, coinciding periodically (best near t = 2.15 s) when x, y "
        "and theta change little",
        _loop(0, 1, 0.3, 3.0),
    ),
    ThesisRun(
        "h2",
        "trident",
        thesis_cycle(3.0),
        "does not match overall; near t = 2.5 s theta is near 0, the joints are in the "
        "ratio 1 : -2 : 1 and the base near the origin",
        _loop(0, 2, 0.2, 3.0),
    ),
    ThesisRun(
        "h3",
        "trident",
        thesis_cycle(2.0),
        "drifts off in -x: the periodic input with these parameters fails",
        _loop(1, 2, 0.25, 2.0),
    ),
    ThesisRun(
        "serpenoid",
        "snake3",
        thesis_cycle(SERPENOID_OMEGA),
        "Figure 20: the serpenoid moves the 3-link snake forward",
    ),
)

RUN_NAMES = tuple(r.name for r in RUNS)


def thesis_runs(only: Sequence[str] = ()) -> list[ThesisRun]:
    """The runs named in ``only``, in the thesis's order; every run without names."""
    return [r for r in RUNS if not only or r.name in only]


@dataclass(frozen=True)
class ThesisResult:
    """One run in both worlds: the commanded table, the model's ideal states (field
    runs), each world's prediction (the emulated record and the table's prediction), and
    how many frames the joint limits clipped."""

    run: ThesisRun
    robot: Robot
    table: GaitTable
    t: np.ndarray
    model_q: np.ndarray | None
    clipped_frames: int
    worlds: dict[str, Prediction]

    def summary(self) -> dict[str, Any]:
        """JSON-able: the run, the thesis's observation, the model's end state (field
        runs) and each world's final state, in the robot's units (and metres)."""
        unit = self.robot.physics.unit_m if self.robot.physics else 1.0
        out: dict[str, Any] = {
            "name": self.run.name,
            "robot": self.robot.name,
            "duration_s": round(self.run.duration_s, 6),
            "frame_period_ms": self.table.frame_period_ms,
            "frames": self.table.frame_count,
            "clipped_frames": self.clipped_frames,
            "thesis_observed": self.run.observed,
            "unit_m": unit,
        }
        if self.model_q is not None:
            out["model"] = _state(self.model_q[-1, :3], self.model_q[-1, 3:])
        for world, result in self.worlds.items():
            rec = result.emulated
            out[world] = _state(rec.pose[-1], rec.phi[-1])  # both worlds start at the origin
            if world == "mujoco":
                extras = result.summary()["emulated"]
                out[world]["slip_distance"] = extras["slip_distance"]
                out[world]["work_j"] = extras["work_j"]
                out[world]["electrical_j"] = extras["electrical_j"]
                out[world]["peak_load"] = extras["peak_load"]
        return out


def _state(pose: np.ndarray, phi: np.ndarray) -> dict[str, Any]:
    return {
        "x": float(pose[0]),
        "y": float(pose[1]),
        "theta": float(pose[2]),
        "phi": [float(v) for v in phi],
    }


def thesis_table(
    run: ThesisRun, robot: Robot
) -> tuple[GaitTable, np.ndarray, np.ndarray | None, int]:
    """The run as a gait table (joint path clipped to the limits, at the finest frame
    period the controller holds), its frame times, the model's states at them (field
    runs) and the number of frames clipped."""
    limit = max_frames(robot.n_joints)
    period_ms = max(FRAME_PERIOD_MS, math.ceil(1000 * run.duration_s / (limit - 1)))
    frames = math.floor(1000 * run.duration_s / period_ms + 1e-9) + 1
    t = np.arange(frames) * period_ms / 1000.0
    phi, model_q = run.joint_path(robot, t)
    low = np.array([j.min_rad for j in robot.joints])
    high = np.array([j.max_rad for j in robot.joints])
    clipped = int(np.any((phi < low) | (phi > high), axis=1).sum())
    ticks = robot.angles_to_ticks(np.clip(phi, low, high))
    table = GaitTable(
        robot.servo_ids,
        period_ms,
        False,
        robot.tick_limits,
        ticks,
        {"robot": robot.name, "thesis_run": run.name},
    )
    return table, t, model_q, clipped


def run_thesis(
    run: ThesisRun, worlds: tuple[str, ...] = WORLDS, mu: float | None = None
) -> ThesisResult:
    """Play ``run`` on its robot in each of ``worlds``."""
    robot = load_robot(run.robot)
    table, t, model_q, clipped = thesis_table(run, robot)
    results = {
        # the thesis's runs stop with the table: so do these (the servos still lag it)
        world: predict_gait(
            table,
            robot,
            world=world,
            mu=mu if world != "kinematic" else None,
            until_rest=False,
        )
        for world in worlds
    }
    return ThesisResult(run, robot, table, t, model_q, clipped, results)
