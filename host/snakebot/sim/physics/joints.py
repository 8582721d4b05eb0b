"""The kinematic world with its servos under the body's load: the physics world's AX-12
actuators (:mod:`snakebot.sim.physics.actuator`: the position controller, the DC motor's
torque-speed line, the gear train's armature) turning the joints of the quasi-static body,
whose wheels' friction loads each joint with the torque the motion needs
(``kin_quasi_static``; docs/models.md, "The quasi-static model beside MuJoCo").

Every control period the servos' registers set the motors' drives through the physics
world's own coupling (``sim_world_couple``); the joints and the body then move over the
period in C (``sim_joints_period``), and the servos report where the joints are. The body
moves with the joints' own steps, by the body velocity their load came from (not from the
samples, as :class:`snakebot.sim.world.World` integrates the servos' motion). The body
has no inertia, so the load follows the joints' motion at once and jumps where the
wheels' sticking and sliding changes (a joint turning, a wheel starting to slide); each
step takes the load implicitly across such a jump (``sim_world.h``).

    world = LoadedWorld(bus, robot)   # as World; make_world picks it for modelled servos
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from snakebot.core import ffi, lib
from snakebot.model.kinematics import KinematicsError
from snakebot.model.kinematics.ccore import c_robot
from snakebot.model.robots import Robot
from snakebot.sim.bus.bus import Bus
from snakebot.sim.physics.actuator import ARMATURE_KG_M2, OVERLOAD_HOLD_S, Actuator
from snakebot.sim.physics.coupling import Arrays, Coupling
from snakebot.sim.physics.mjcf import CONTROL_PERIOD_S, physics_of
from snakebot.sim.world import DEFAULT_PERIOD_S, World

JOINT_STEP_S = 0.001
"""The joints' step (at most; shortened to divide the control period). The load jumps with
the wheels' sticking and sliding, so the motion converges in the step only to first order:
at 1 ms snake5's serpenoids go within 3.3 % of their distance at 0.01 ms (A = 20 deg,
delta = 150 deg, the most sensitive; at 0.05 ms: 1.5 % at A = 30 deg, delta = 150 deg,
omega = 90 deg/s, 1.0 % at A = 20 deg, delta = 120 deg, 0.2 % at delta <= 90 deg), at a
cost of about 20 quasi-static solutions per 10 ms control period."""


def loads_its_servos(bus: Bus, robot: Robot) -> bool:
    """Whether the kinematic world on ``bus`` turns the servos of ``robot`` itself: they
    are modelled AX-12s (ideal ones are where they are told at once) and the robot has
    the masses that set its wheels' load (``[physics]``)."""
    servos = [s for s in bus.servos if s.id in robot.servo_ids]
    return robot.physics is not None and not any(s.ideal for s in servos)


class LoadedWorld(World):
    """:class:`World`, its joints turned by the servos' motors under the body's load.

    As :class:`World` (``batch`` is not used: the body moves with the joints), plus
    ``control_period`` and ``step``: at most these, shortened to divide ``period`` and
    the control period. :attr:`load` is each joint's load in the last step (N m)."""

    def __init__(
        self,
        bus: Bus,
        robot: Robot,
        *,
        period: float = DEFAULT_PERIOD_S,
        control_period: float = CONTROL_PERIOD_S,
        step: float = JOINT_STEP_S,
        **options: Any,
    ) -> None:
        self.steps_per_sample = max(1, math.ceil(period / control_period - 1e-9))
        self.control_period = period / self.steps_per_sample
        steps = max(1, math.ceil(self.control_period / step - 1e-9))
        self._ticks = 0
        super().__init__(bus, robot, period=period, **options)
        n = robot.n_joints
        for servo in self._servos:
            servo.advance(self.start_time)
        # the state: the pose, then the joints where the servos are
        positions = np.array([s.pos for s in self._servos])
        self._state = np.concatenate([self._pose, robot.ticks_to_angles(positions)])
        self._slip = np.zeros(robot.n_wheels)
        self.load = np.zeros(n)
        arrays = Arrays(
            self._state[3:],
            np.zeros(n),
            np.zeros(n),
            np.zeros((n, 2)),
            np.zeros((n, 2)),
            self.control_period / steps,
        )
        self._signs = np.array([float(j.sign) for j in robot.joints])
        joints = zip(
            self._servos,
            self._signs.tolist(),
            [float(j.zero_tick) for j in robot.joints],
            range(n),
            range(n),
            strict=True,
        )
        self._coupling = Coupling(
            arrays,
            list(joints),
            Actuator.for_model(robot.servo_model),
            hold=OVERLOAD_HOLD_S,
            period=self.control_period,
            start=self.start_time,
            min_z=0.0,
            pieces=(),
            profile=robot.speed_limit == "profile",
        )
        self._arrays = arrays
        c = self._c = ffi.new("sim_joints *")
        c.world = self._coupling.c
        c.rb = self._rb = c_robot(robot, self.friction)
        c.unit_m = physics_of(robot).unit_m
        c.armature = ARMATURE_KG_M2
        c.steps = steps
        # the middle of a sample's interval: a step of one of its control periods
        self._slip_period, self._slip_step = divmod(self.steps_per_sample * steps // 2, steps)
        self._external = np.zeros(n)
        self._stops = (  # the joints' stops, the physics world's joint ranges
            np.array([j.min_rad for j in robot.joints]),
            np.array([j.max_rad for j in robot.joints]),
        )
        c.q, c.speed, c.force, c.load, c.slip, c.external, c.lo, c.hi = (
            ffi.from_buffer("double[]", a, require_writable=True)
            for a in (
                self._state,
                arrays.qvel,
                arrays.force,
                self.load,
                self._slip,
                self._external,
                *self._stops,
            )
        )

    def _schedule_sampling(self) -> Any:
        return self.bus.every(self.control_period, self._tick, start=self.start_time)

    def _tick(self, t: float) -> None:
        """At bus time ``t``: move the joints and the body from the last tick to ``t``
        under the drives set then, report the joints to the servos, sample if a sample
        is due, and set every motor's drive from its servo's registers as they are now."""
        if not self._running:
            return
        world = self._coupling.c
        if self._ticks:
            into = (self._ticks - 1) % self.steps_per_sample  # this period in its sample's
            self._c.slip_step = self._slip_step if into == self._slip_period else -1
            # a push on a servo's horn (its set_external_torque) turns its joint too
            self._external[:] = [s.external_torque for s in self._servos]
            self._external *= self._signs
            code = lib.sim_joints_period(self._c)
            if code != lib.KIN_OK:
                self.stop()
                raise self._error(0, 1, KinematicsError(code))
        else:
            lib.sim_world_measure(world)
        lib.sim_world_couple(world, t)
        if self._ticks % self.steps_per_sample == 0:
            # the state and the wheels' slip (none at the first sample: nothing has moved)
            slip = self._slip if self._history.total else np.zeros_like(self._slip)
            self._append(self._state[None, :], slip[None, :])
            self._pose = self._state[:3].copy()
        self._ticks += 1

    def stop(self) -> None:
        """Stop (what was sampled stays in the record); the servos move by their own
        model again."""
        if self._running:
            super().stop()
            for servo in self._servos:
                servo.world_driven = False
