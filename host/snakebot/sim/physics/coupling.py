"""The physics world's per-tick work in C (``host/snakebot/sim/csrc/sim_world.c``): a
``sim_world`` struct that points at MuJoCo's arrays, the servos' structs and the joints'
state, made once per world, so a control tick is a MuJoCo step and a few C calls with no
Python objects made per joint.

    coupling = Coupling(Arrays.of(model, data), joints, actuator, hold=..., period=..., ...)
    lib.sim_world_couple(coupling.c, t)     # every servo's registers to its drive
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from snakebot.core import ffi
from snakebot.model.robots import TICKS_PER_RAD
from snakebot.sim.physics.actuator import DUTY_FULL, STALLED_FRACTION, Actuator
from snakebot.sim.servo import motor
from snakebot.sim.servo.fast import VirtualServo


def actuator_struct(actuator: Actuator) -> Any:
    """``actuator``'s constants as the C's ``sim_actuator *``."""
    return ffi.new(
        "sim_actuator *",
        {
            "stall_nm": actuator.stall_nm,
            "nominal_v": actuator.nominal_v,
            "no_load_rad_s": actuator.no_load_rad_s,
            "ticks_per_rad": TICKS_PER_RAD,
            "duty_full": DUTY_FULL,
            "direction_bit": motor.DIRECTION_BIT,
        },
    )


@dataclass(frozen=True)
class Arrays:
    """What the coupling works on in place: the joints' angles and speeds (``qpos``,
    ``qvel``, where the joints' indices point), each motor's torque (``force``), each
    drive's row of bias parameters (``biasprm``: the torque bias[0] + bias[1] angle) and
    its force range (``forcerange``, low and high), and the step the motors' energy is
    accounted over (``timestep``, s). MuJoCo's own arrays (:meth:`of`), or a world's that
    moves the joints itself."""

    qpos: np.ndarray
    qvel: np.ndarray
    force: np.ndarray
    biasprm: np.ndarray
    forcerange: np.ndarray
    timestep: float

    @classmethod
    def of(cls, model: Any, data: Any) -> Arrays:
        """MuJoCo's: a compiled model's and its data's."""
        return cls(
            data.qpos,
            data.qvel,
            data.actuator_force,
            model.actuator_biasprm,
            model.actuator_forcerange,
            model.opt.timestep,
        )


class Coupling:
    """The ``sim_world`` of one world (:attr:`c`) and everything it points to, kept alive
    here. ``joints``: per joint its servo, sign, tick at angle 0, qpos and qvel index.
    ``pieces``: a sample's row after its time, each a MuJoCo array (any shape, read flat)
    and the flat indices to take from it; each joint's motor torque follows them.
    ``z``: the qpos indices of the slides in z from the root down the chain, a link's
    height their sum up to its own; a sample with any below ``min_z`` has sunk.
    :attr:`energy` and :attr:`electrical` are the motors' running totals (J). ``profile``:
    Moving Speed moves each drive's target instead of capping the drive (the robot's
    ``speed_limit``)."""

    def __init__(
        self,
        arrays: Arrays,
        joints: Sequence[tuple[VirtualServo, float, float, int, int]],
        actuator: Actuator,
        *,
        hold: float,
        period: float,
        start: float,
        min_z: float,
        z: Sequence[int] = (),
        pieces: Sequence[tuple[np.ndarray, Sequence[int]]],
        profile: bool = False,
    ) -> None:
        n = len(joints)
        servos, sign, zero, qadr, dadr = zip(*joints, strict=True)
        self.energy = np.zeros(n)
        self.electrical = np.zeros(n)
        self.torque = np.zeros(n)
        self._keep: list[Any] = []
        c = self.c = self._new("sim_world *")
        c.n = n
        c.servos = self._new("sim_servo *[]", [s.c_struct for s in servos])
        c.sign, c.zero = self._doubles(sign), self._doubles(zero)
        c.qadr, c.dadr = self._ints(qadr), self._ints(dadr)
        c.qpos, c.qvel = self._doubles(arrays.qpos), self._doubles(arrays.qvel)
        c.force = self._doubles(arrays.force)
        c.nq, c.nv = len(arrays.qpos), len(arrays.qvel)
        c.biasprm = self._doubles(arrays.biasprm)
        c.forcerange = self._doubles(arrays.forcerange)
        c.nbias = arrays.biasprm.shape[1]
        c.actuator = self._held(actuator_struct(actuator))
        c.brake = -actuator.damping
        c.stalled_fraction = STALLED_FRACTION
        c.hold, c.period, c.dt = hold, period, arrays.timestep
        c.start, c.min_z = start, min_z
        c.zadr, c.nz = self._ints(z), len(z)
        pieces = [*pieces, (self.torque, range(n))]
        gathers = c.gathers = self._new("sim_gather[]", len(pieces))
        c.ngathers = len(pieces)
        for gather, (source, index) in zip(gathers, pieces, strict=True):
            gather.source, gather.index = self._doubles(source), self._ints(index)
            gather.n = len(index)
        c.speed, c.torque = self._doubles(np.zeros(n)), self._doubles(self.torque)
        c.energy, c.electrical = self._doubles(self.energy), self._doubles(self.electrical)
        c.stalled = self._doubles(np.zeros(n))
        c.on, c.moving = (self._held(ffi.new("_Bool[]", n)) for _ in range(2))
        c.profile = int(profile)
        c.reference = self._doubles(np.zeros(n))
        self.width = 1 + sum(len(index) for _, index in pieces)
        """A sample's row length."""

    def _held(self, obj: Any) -> Any:
        self._keep.append(obj)
        return obj

    def _new(self, ctype: str, init: Any = None) -> Any:
        return self._held(ffi.new(ctype, init))

    def _doubles(self, values: Any) -> Any:
        """A ``double *`` to ``values`` itself if it is a C-contiguous float64 array (MuJoCo's,
        or state the C updates), else to a copy."""
        array = values if isinstance(values, np.ndarray) else np.array(values, dtype=np.float64)
        if array.dtype != np.float64 or not array.flags.c_contiguous:
            raise ValueError("the C coupling needs C-contiguous float64 arrays")
        self._held(array)
        return self._held(ffi.from_buffer("double[]", array, require_writable=True))

    def _ints(self, values: Any) -> Any:
        return self._new("int[]", [int(v) for v in values])
