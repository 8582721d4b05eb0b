"""The physics world: the robot's body on a floor, in MuJoCo, moved by AX-12 actuators that
the virtual servos' registers command.

It has the interface of the kinematic :class:`snakebot.sim.world.World` (built on a bus,
sampling every ``period`` of bus time, ``pose``, ``record()``, ``stop()``), but the
servos do not move themselves: every control period (``control_period`` of bus time) the
world reads each servo's controller registers, works out its motor's drive
(:mod:`snakebot.sim.physics.actuator`), steps MuJoCo over the period, and reports the
joint's position, speed and load back to the servo
(:meth:`snakebot.sim.servo.fast.VirtualServo.set_motion`), so a master reading Present
Position, Present Speed or Present Load over the bus sees the physics, and a joint that
cannot deliver the torque asked of it reports overload.

The record is the kinematic world's (pose in the robot's length units, joint angles,
each wheel's sideways slip speed) plus each joint's motor torque, load and the energy it
put in (the integral of torque times joint speed; negative while the joint is driven
backwards).

    world = PhysicsWorld(bus, robot)   # samples from now, every 10 ms of bus time
    bus.run_until(bus.now + 2.0)       # ... while a master drives the servos
    rec = world.record()
"""

from __future__ import annotations

import copy
import functools
import math
from collections import deque
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from snakebot.core import ffi, lib
from snakebot.formats.live_topics import Shape
from snakebot.model.robots import TICKS_PER_RAD, Friction, Robot
from snakebot.sim.bus.bus import Bus
from snakebot.sim.history import History
from snakebot.sim.physics.actuator import OVERLOAD_HOLD_S, Actuator
from snakebot.sim.physics.coupling import Arrays, Coupling
from snakebot.sim.physics.mjcf import (
    CONTROL_PERIOD_S,
    ROLLING_MODEL,
    TIMESTEP_S,
    build_mjcf,
    physics_of,
)
from snakebot.sim.world import DEFAULT_PERIOD_S, WorldError, WorldRecord, require_servos

PENETRATION_LIMIT = 0.5
"""A wheel whose centre sinks below this fraction of its radius means the contact solver
has failed: the run stops."""


_FAILURES = {
    lib.SIM_WORLD_BLEW_UP: "the simulation blew up (a position or speed is not finite)",
    lib.SIM_WORLD_SANK: "the wheels sank deep into the floor",
}
"""What each failure the coupling's sample check finds is, in words."""


class PhysicsError(WorldError):
    """The physics cannot go on (blow-up, deep penetration) or cannot start."""


def _mujoco() -> Any:
    try:
        import mujoco
    except ImportError:  # pragma: no cover - mujoco is a dev and physics dependency
        raise PhysicsError(
            "the physics world needs MuJoCo: pip install 'snakebot[physics]' (make setup "
            "installs it)"
        ) from None
    global _warnings_kept
    if not _warnings_kept:
        # MuJoCo's own handler appends every warning (a blow-up's "Nan, Inf or huge
        # value") to MUJOCO_LOG.TXT in the working directory; the worlds read the warning
        # counters instead, so the text is kept here, the last few, and no file is made.
        mujoco.set_mju_user_warning(_keep_warning)
        _warnings_kept = True
    return mujoco


@functools.lru_cache(maxsize=8)
def _compiled(robot: Robot, timestep: float, friction: Friction, rolling_model: str) -> Any:
    """The model of ``robot`` (:func:`build_mjcf`) compiled, and its names, made once per
    process: a search builds a world for every run, mostly of the same few models (a
    copy of the compiled model takes a quarter of the time of compiling)."""
    xml, names = build_mjcf(
        robot, timestep=timestep, friction=friction, rolling_model=rolling_model
    )
    return _mujoco().MjModel.from_xml_string(xml), names


_warnings_kept = False
MUJOCO_WARNINGS: deque[str] = deque(maxlen=16)
"""MuJoCo's last warnings, newest last."""


def _keep_warning(message: str) -> None:
    MUJOCO_WARNINGS.append(message)


@dataclass(frozen=True)
class PhysicsRecord(WorldRecord):
    """:class:`WorldRecord` plus, per sample and joint, the motor ``torque`` (N m at the
    joint, + in the joint's positive direction) and ``load`` (fraction of the stall
    torque); per joint the mechanical work ``energy`` put in (J, signed: negative while
    the joint is driven backwards) and the ``electrical`` energy its motor drew (J, the DC
    motor model of :meth:`snakebot.sim.servo.motor.MotorSpec.electrical_power_w`); and the
    wheel-floor ``mu``."""

    torque: np.ndarray
    load: np.ndarray
    energy: np.ndarray
    electrical: np.ndarray
    mu: float
    timestep: float

    def physics_summary(self) -> dict[str, Any]:
        """What the physics adds to a report: per wheel the largest sideways slip speed
        (robot length units per second; the distance slid is ``slip_distance``), per
        joint the energy (J) and the peak load (fraction of stall torque)."""
        slip = np.abs(self.slip)
        return {
            "friction": asdict(self.friction),
            "mu": self.mu,
            "timestep_s": self.timestep,
            "wheel_slip_speed_max": [float(v) for v in slip.max(axis=0)]
            if len(slip)
            else [0.0] * self.slip.shape[1],
            "work_j": [float(v) for v in self.energy],
            "electrical_j": [float(v) for v in self.electrical],
            "peak_load": [float(v) for v in self.load.max(axis=0)]
            if len(self.load)
            else [0.0] * self.load.shape[1],
        }


class PhysicsWorld:
    """The body of ``robot`` in MuJoCo, driven by the servos on ``bus``.

    Sampling starts at bus time ``start`` (default: now), every ``period`` seconds until
    :meth:`stop`; the control period and the MuJoCo step are at most ``control_period``
    and ``timestep``, shortened to divide the sampling period. ``keep``: how many of the
    latest samples the record keeps (default all; a server that runs for days keeps
    few). ``pose`` is the body pose at the start (robot units, radians); the joints
    start where the servos are. ``mu`` overrides the wheel-floor Coulomb coefficient
    (``[friction] lateral``); ``rolling_model`` how rolling resistance enters MuJoCo
    (:data:`snakebot.sim.physics.mjcf.ROLLING_MODELS`).
    """

    def __init__(
        self,
        bus: Bus,
        robot: Robot,
        *,
        period: float = DEFAULT_PERIOD_S,
        start: float | None = None,
        pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
        mu: float | None = None,
        timestep: float = TIMESTEP_S,
        control_period: float = CONTROL_PERIOD_S,
        keep: int | None = None,
        rolling_model: str = ROLLING_MODEL,
    ) -> None:
        mujoco = _mujoco()
        if not min(period, timestep, control_period) > 0:
            raise PhysicsError(
                f"the world's period ({period}), control period ({control_period}) and time "
                f"step ({timestep}) must be positive"
            )
        phys = physics_of(robot)
        ids = require_servos(bus, robot)
        # the sampling period is kept exactly; control period and step shrink to divide it
        self.steps_per_sample = max(1, math.ceil(period / control_period - 1e-9))
        self.period = float(period)
        self.control_period = self.period / self.steps_per_sample
        self.substeps = max(1, math.ceil(self.control_period / timestep - 1e-9))
        self.timestep = self.control_period / self.substeps
        self.friction = robot.friction if mu is None else replace(robot.friction, lateral=mu)
        compiled, names = _compiled(robot, self.timestep, self.friction, rolling_model)
        self._mj = mujoco
        # a copy of its own: the world writes the drives into the model
        self.model = copy.copy(compiled)
        self.data = mujoco.MjData(self.model)
        self.bus = bus
        self.robot = robot
        self.unit = phys.unit_m
        self.mu = self.friction.lateral
        self.start_time = bus.now if start is None else float(start)
        self.actuator = Actuator.for_model(robot.servo_model)
        self._servos = [bus.servo(i) for i in ids]
        signs = [float(j.sign) for j in robot.joints]
        self._signs = np.array(signs)
        zeros = [float(j.zero_tick) for j in robot.joints]
        m = self.model
        jid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names.joints]
        self._qadr = [int(m.jnt_qposadr[j]) for j in jid]
        self._dadr = [int(m.jnt_dofadr[j]) for j in jid]
        self._wheels = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, n) for n in names.wheels]
        # the base slides in z from the wheels' resting height (their radius), each link
        # of a snake in z on its parent
        self._min_z = (PENETRATION_LIMIT - 1.0) * phys.wheel_radius_m
        heights = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names.heights]
        self._heights = [int(m.jnt_qposadr[j]) for j in heights]
        d = self.data
        d.qpos[0], d.qpos[1], d.qpos[3] = pose[0] * self.unit, pose[1] * self.unit, pose[2]
        for k, servo in enumerate(self._servos):
            servo.advance(self.start_time)
            d.qpos[self._qadr[k]] = (servo.pos - zeros[k]) / (signs[k] * TICKS_PER_RAD)
        mujoco.mj_forward(m, d)
        self._ticks = 0
        self._running = True
        self._root = int(m.body_rootid[self._wheels[0]])
        # what a sample keeps: x, y, theta and the joints; per wheel its turn rate and
        # velocity (x, y) about the root's centre of mass, its centre (x, y), the root's
        # centre of mass (x, y), each wheel's axle; then (the coupling adds it) each
        # joint's motor torque
        w = np.array(self._wheels)
        pieces = [
            (d.qpos, [0, 1, 3, *self._qadr]),
            (d.cvel, (6 * w[:, None] + [2, 3, 4]).ravel()),
            (d.xpos, (3 * w[:, None] + [0, 1]).ravel()),
            (d.subtree_com, [3 * self._root, 3 * self._root + 1]),
            (d.xmat, (9 * w[:, None] + [1, 4]).ravel()),  # row-major 3x3: column 1
        ]
        joints = zip(self._servos, signs, zeros, self._qadr, self._dadr, strict=True)
        self._coupling = Coupling(
            Arrays.of(m, d),
            list(joints),
            self.actuator,
            hold=OVERLOAD_HOLD_S,
            period=self.control_period,
            start=self.start_time,
            min_z=self._min_z,
            z=self._heights,
            pieces=pieces,
            profile=robot.speed_limit == "profile",
        )
        self._c = self._coupling.c
        # a sample's row: its time, then the pieces (their widths say where each ends)
        widths = [1, *(len(index) for _, index in pieces), robot.n_joints]
        ends = np.cumsum(widths).tolist()
        self._cols = [slice(end - width, end) for width, end in zip(widths, ends, strict=True)]
        self._history = History(self._coupling.width, keep)
        self._row = np.zeros(self._coupling.width)
        self._row_c = ffi.from_buffer("double[]", self._row, require_writable=True)
        self._schedule = bus.every(self.control_period, self._tick, start=self.start_time)

    # -- stepping -------------------------------------------------------------------------

    def _tick(self, t: float) -> None:
        """At bus time ``t``: bring the physics from the last tick to ``t`` under the
        drive set then, report the joints to the servos (and record, if a sample is
        due), and set every motor's drive from its servo's registers as they are now.

        Once per control period: MuJoCo's steps, and the per-joint work in C
        (:mod:`snakebot.sim.physics.coupling`) on MuJoCo's arrays in place."""
        if not self._running:
            return
        world = self._c
        if self._ticks:
            # a push on a servo's horn (its set_external_torque) turns its joint too
            pushes = [s.external_torque for s in self._servos]
            self.data.qfrc_applied[self._dadr] = self._signs * pushes
            # energy: the motors' power (the drive in force during each step, the speed
            # at its end; the implicit integrator's own reading of the step)
            step, m, d, account = self._mj.mj_step, self.model, self.data, lib.sim_world_account
            for _ in range(self.substeps):
                step(m, d)
                account(world)
        else:
            lib.sim_world_measure(world)
        if self._ticks % self.steps_per_sample == 0:
            self._sample(t)
        self._ticks += 1
        lib.sim_world_couple(world, t)

    def _sample(self, t: float) -> None:
        """Check the physics is sane and keep what the record is made of (raw: the record
        works the slip out for all samples at once)."""
        failed = lib.sim_world_sample(self._c, t, self._row_c)
        if failed:
            self._fail(t, _FAILURES[failed])
        self._history.slot()[:] = self._row

    def _fail(self, t: float, what: str) -> None:
        self.stop()
        raise PhysicsError(
            f"{what} at {t - self.start_time:.3f} s of world time: the run is stopped; "
            "check the robot's [physics] table (masses, wheel radius) and [friction] for "
            "values far from a real robot's, or play a gentler gait"
        )

    def stop(self) -> None:
        """Stop stepping (what was sampled stays in the record); the servos move by
        their own model again."""
        if self._running:
            self._schedule.cancel()
            self._running = False
            for servo in self._servos:
                servo.world_driven = False

    @property
    def running(self) -> bool:
        return self._running

    # -- results --------------------------------------------------------------------------

    @property
    def pose(self) -> np.ndarray:
        """The body pose (x, y, theta) now, in robot units."""
        q = self.data.qpos
        return np.array([q[0] / self.unit, q[1] / self.unit, q[3]])

    @property
    def samples(self) -> int:
        return len(self._history)

    @functools.cached_property
    def shapes(self) -> list[Shape]:
        """The robot's bodies for a 3-D scene: each geom as a box, cylinder or sphere (a
        capsule as the cylinder around it; metres) in the frame of its body, named as the
        exported URDF names its link, so the links' transforms move them. The floor is not
        among them. Made once: a body's geoms do not move within it."""
        types = self._mj.mjtGeom
        m = self.model
        shapes = []
        for g in range(m.ngeom):
            t = int(m.geom_type[g])
            a, b, c = (float(v) for v in m.geom_size[g])
            body = int(m.geom_bodyid[g])
            if body == 0:
                continue  # the floor's
            if t in (int(types.mjGEOM_BOX), int(types.mjGEOM_ELLIPSOID)):
                kind, size = (
                    "cube" if t == int(types.mjGEOM_BOX) else "sphere",
                    (2 * a, 2 * b, 2 * c),
                )
            elif t in (int(types.mjGEOM_CYLINDER), int(types.mjGEOM_CAPSULE)):
                length = 2 * b + (2 * a if t == int(types.mjGEOM_CAPSULE) else 0.0)
                kind, size = "cylinder", (2 * a, 2 * a, length)
            elif t == int(types.mjGEOM_SPHERE):
                kind, size = "sphere", (2 * a, 2 * a, 2 * a)
            else:
                continue  # a mesh or a plane: not drawn
            w, x, y, z = m.geom_quat[g].tolist()
            frame = self._mj.mj_id2name(m, self._mj.mjtObj.mjOBJ_BODY, body)
            position = tuple(m.geom_pos[g].tolist())
            shapes.append(Shape(kind, size, position, (x, y, z, w), frame))  # type: ignore[arg-type]
        return shapes

    def record(self) -> PhysicsRecord:
        """Everything sampled so far."""
        w = self.robot.n_wheels
        rows = self._history.array()
        times, state, cvel, centre, com, axle, torque = (rows[:, c] for c in self._cols)
        # each wheel centre's velocity along its axle, from the com-based velocities (the
        # robot is one tree rooted at the base): v + w x r. The robot stays level, so of
        # w only the turn about z moves a centre sideways (the spin is along the axle).
        cvel = cvel.reshape(len(rows), w, 3)
        centre = centre.reshape(len(rows), w, 2)
        axle = axle.reshape(len(rows), w, 2)
        r = centre - com[:, None, :]
        vx = cvel[:, :, 1] - cvel[:, :, 0] * r[:, :, 1]
        vy = cvel[:, :, 2] + cvel[:, :, 0] * r[:, :, 0]
        slip = (vx * axle[:, :, 0] + vy * axle[:, :, 1]) / self.unit
        pose = state[:, :3] / [self.unit, self.unit, 1.0]
        return PhysicsRecord(
            times[:, 0],
            pose,
            state[:, 3:],
            slip,
            self.friction,
            torque,
            np.abs(torque) / self.actuator.stall_nm,
            self._coupling.energy.copy(),
            self._coupling.electrical.copy(),
            self.mu,
            self.timestep,
        )
