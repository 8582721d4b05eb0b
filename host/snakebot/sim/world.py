"""The world: the robot's body on the floor, moved by its virtual servos.

The servos' shaft angles are the joint angles: each servo's continuous position in ticks
(its motion model's ``pos``, through the joint's zero tick and sign), not the whole ticks
its Present Position register reports to a READ. The kinematic core's quasi-static friction
model (``snakebot.model.kinematics``, in C) turns the joint motion into body motion. The
world samples the positions every ``period`` seconds of bus time
(:meth:`snakebot.sim.bus.bus.Bus.every`), takes the joints as moving linearly between
samples, and integrates the body over the samples in batches:
one C call per batch of intervals (the core steps each interval separately, so the
kinks between intervals cost no accuracy), never a Python loop per step. The servos
move by their own model here (ideal ones: at once); modelled AX-12s get the world of
:mod:`snakebot.sim.physics.joints` (``make_world``), which turns them under the body's
load.

Wheels: the robot's friction (``[friction]``: Coulomb across the wheels, rolling resistance
along them), the same as the physics world's. The body moves as the friction forces
balance (no inertia), so where the joints ask for a motion the wheels cannot follow
without slipping (a singular configuration, or more than three wheels) they slip; the
record holds each wheel's sideways (normal) speed at every sample.

    world = World(bus, robot)          # samples from now, every 10 ms of bus time
    bus.run_until(bus.now + 2.0)       # ... while a master drives the servos
    rec = world.record()               # t, pose (x, y, theta), phi, slip
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from snakebot.errors import InputError
from snakebot.model.gait.common import PREDICT_OPTIONS
from snakebot.model.kinematics import KinematicsError, Options, Table, integrate_joints
from snakebot.model.robots import Friction, Robot
from snakebot.sim.bus.bus import Bus
from snakebot.sim.history import History

DEFAULT_PERIOD_S = 0.01
"""How often the world samples the servos: 100 Hz of bus time."""

DEFAULT_BATCH = 256
"""Samples integrated per C call (fewer when the pose is asked for sooner)."""


class WorldError(InputError):
    """The world cannot move the body as the servos ask (see the message for the fix)."""


@dataclass(frozen=True)
class WorldRecord:
    """What the world saw: ``t[k]`` (seconds since the world started), the body pose
    ``pose[k] = (x, y, theta)`` (reference point and heading of link 1 / the base),
    the joint angles ``phi[k]`` (radians), each wheel's normal slip speed ``slip[k]``
    (length units per second, in the middle of the interval ending at ``t[k]``), and
    the ``friction`` the world had."""

    t: np.ndarray
    pose: np.ndarray
    phi: np.ndarray
    slip: np.ndarray
    friction: Friction

    @property
    def q(self) -> np.ndarray:
        """Full states (x, y, theta, phi...) per sample."""
        return np.hstack([self.pose, self.phi])

    def displacement(self) -> dict[str, float]:
        """Final minus first pose: (dx, dy) in the first pose's frame, and dtheta."""
        start, end = self.pose[0], self.pose[-1]
        c, s = np.cos(start[2]), np.sin(start[2])
        dx, dy = end[0] - start[0], end[1] - start[1]
        return {
            "dx": float(c * dx + s * dy),
            "dy": float(-s * dx + c * dy),
            "dtheta": float(end[2] - start[2]),
        }

    def slip_max(self) -> float:
        """Largest sideways slip speed of any wheel at any sample."""
        return float(np.abs(self.slip).max()) if self.slip.size else 0.0

    def slip_distance(self) -> np.ndarray:
        """Per wheel, the distance slid sideways (integral of |slip speed|, trapezoid over
        the samples: an estimate as good as the sampling)."""
        if len(self.t) < 2:
            return np.zeros(self.slip.shape[1])
        speed = np.abs(self.slip)
        return ((speed[1:] + speed[:-1]) * 0.5 * np.diff(self.t)[:, None]).sum(axis=0)


def integrate_samples(
    robot: Robot,
    angles: np.ndarray,
    period: float,
    pose0: np.ndarray,
    friction: Friction,
    options: Options,
) -> tuple[np.ndarray, np.ndarray]:
    """Body states at joint samples ``angles`` (rows every ``period``, linear in between)
    from ``pose0``, in one C call: q (rows x (3 + joints); the angles are the samples
    themselves) and each wheel's slip speed in the middle of the interval ending at each
    row (zeros for row 0). Mid-interval, because at a sample the joint velocity jumps."""
    n = len(angles)
    traj = integrate_joints(
        robot,
        Table(angles, period),
        (n - 1) * period,
        pose0=tuple(pose0),
        samples=2 * n - 1,
        options=options,
        friction=friction,
        with_slip=True,
    )
    assert traj.slip is not None
    q = traj.q[::2].copy()
    q[:, 3:] = angles
    slip = np.vstack([np.zeros((1, traj.slip.shape[1])), traj.slip[1::2]])
    return q, slip


def require_servos(bus: Bus, robot: Robot) -> tuple[int, ...]:
    """The robot's servo IDs, once checked to be on the bus (a world drives them all)."""
    ids = robot.servo_ids
    missing = [i for i in ids if all(s.id != i for s in bus.servos)]
    if missing:
        raise WorldError(
            f"{robot.name} drives servos {list(ids)} but the bus has no servo with ID "
            f"{', '.join(map(str, missing))}: build the bus for this robot "
            f"(sim://?robot={robot.source or robot.name})"
        )
    return ids


class World:
    """The body of ``robot`` driven by the servos on ``bus``.

    Sampling starts at bus time ``start`` (default: now) and repeats every ``period``
    seconds until :meth:`stop`. ``pose`` is the body pose at the first sample.
    ``friction`` overrides the robot's; ``options`` the integrator (default: the gait
    predictions' Dormand-Prince settings). A motion the model cannot integrate raises
    :class:`WorldError` (from the bus call that ran the sample, or from :meth:`record`).
    The servos are looked up by ID once, here.
    ``keep`` bounds the record for worlds that run for hours: the latest ``keep``
    samples are kept (in a ring allocated at the start), the oldest dropped; None keeps
    everything.
    """

    def __init__(
        self,
        bus: Bus,
        robot: Robot,
        *,
        period: float = DEFAULT_PERIOD_S,
        start: float | None = None,
        pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
        friction: Friction | None = None,
        options: Options | None = None,
        batch: int = DEFAULT_BATCH,
        keep: int | None = None,
    ) -> None:
        if not period > 0:
            raise WorldError(f"the world's sampling period must be positive, not {period}")
        if batch < 1:
            raise WorldError(f"batch must be at least 1 sample, not {batch}")
        if keep is not None and keep < 1:
            raise WorldError(f"keep must be at least 1 sample, not {keep}")
        ids = require_servos(bus, robot)
        self.bus = bus
        self.robot = robot
        self.period = float(period)
        self.friction = robot.friction if friction is None else friction
        self.options = options or PREDICT_OPTIONS
        self.batch = batch
        self.start_time = bus.now if start is None else float(start)
        self._servos = [bus.servo(i) for i in ids]
        self._running = True
        self._pending: list[list[float]] = []  # tick rows not integrated yet
        self._last_ticks: list[float] | None = None  # the last integrated sample
        self._pose = np.array(pose, dtype=float)
        # the record: per sample the state (pose, joints) and each wheel's slip
        self.keep = keep
        self._history = History(3 + robot.n_joints + robot.n_wheels, keep)
        self._schedule = self._schedule_sampling()

    def _schedule_sampling(self) -> Any:
        """Sample the servos every period from the start (a world that moves the joints
        itself schedules its own steps)."""
        return self.bus.every(self.period, self._sample, start=self.start_time)

    # -- sampling -------------------------------------------------------------------------

    def _sample(self, t: float) -> None:
        row = []
        for s in self._servos:
            s.advance(t)
            row.append(s.pos)
        self._pending.append(row)
        if len(self._pending) >= self.batch:
            self.flush()

    def stop(self) -> None:
        """Stop sampling (what was sampled stays in the record)."""
        self.flush()
        self._schedule.cancel()
        self._running = False

    @property
    def running(self) -> bool:
        return self._running

    # -- integration ----------------------------------------------------------------------

    def flush(self) -> None:
        """Integrate the body over every sample taken so far."""
        pending = self._pending
        if not pending:
            return
        self._pending = []
        robot = self.robot
        if self._last_ticks is None:  # the very first sample: the body is where it starts
            angles = robot.ticks_to_angles(np.asarray(pending[0], dtype=float))
            self._append(
                np.concatenate([self._pose, angles])[None, :], np.zeros((1, robot.n_wheels))
            )
            self._last_ticks = pending[0]
            pending = pending[1:]
            if not pending:
                return
        angles = robot.ticks_to_angles(np.asarray([self._last_ticks, *pending], dtype=float))
        try:
            q, slip = integrate_samples(
                robot, angles, self.period, self._pose, self.friction, self.options
            )
        except KinematicsError as exc:
            raise self._error(0, len(pending), exc) from exc
        self._append(q[1:], slip[1:])
        self._pose = q[-1, :3].copy()
        self._last_ticks = pending[-1]

    def _error(self, first: int, count: int, exc: KinematicsError) -> WorldError:
        t_a = (self._history.total - 1 + first) * self.period
        return WorldError(
            f"the body cannot follow the servos between {t_a:.3f} s and "
            f"{t_a + count * self.period:.3f} s of world time: {exc}"
        )

    def _append(self, q: np.ndarray, slip: np.ndarray) -> None:
        self._history.extend(np.column_stack((q, slip)))

    # -- results --------------------------------------------------------------------------

    @property
    def pose(self) -> np.ndarray:
        """The body pose (x, y, theta) at the latest sample."""
        self.flush()
        return self._pose.copy()

    @property
    def samples(self) -> int:
        """Samples taken so far."""
        return self._history.total + len(self._pending)

    def record(self) -> WorldRecord:
        """Everything sampled so far (integrating what is pending first); with ``keep``,
        the latest ``keep`` samples (``t`` still counts from the world's start)."""
        self.flush()
        robot = self.robot
        rows = self._history.array()
        t = (self._history.dropped + np.arange(len(rows))) * self.period
        n = robot.n_joints
        return WorldRecord(
            t,
            rows[:, :3],
            rows[:, 3 : 3 + n],
            rows[:, 3 + n :],
            self.friction,
        )
