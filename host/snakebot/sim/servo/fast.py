"""The emulator's servo: :class:`~snakebot.sim.servo.reference.ReferenceServo` with its
hot path in C.

The reference model is Python, written to be read; a closed loop spends most of its
time in a few of its paths: the motion, heat and alarms between packets, the telemetry
READ and the Goal Position (+ Moving Speed) write that every SYNC_WRITE carries, and a
physics world's hooks (its report of the joint, the controller it reads back). Those
run in C here (``host/snakebot/sim/csrc/sim_servo.c``, built into ``snakebot._core``),
on state kept in one C struct: every attribute those paths use is a property reading
and writing the struct, so the reference model's own methods (every other instruction,
power) work on the same servo unchanged. The control table
stays the register file's ``bytearray``; the struct points into it.

``tests/sim/test_fast_servo.py`` holds the two to the same replies, registers and
motion, bit for bit, on random packet streams.
"""

from __future__ import annotations

from operator import attrgetter
from typing import Any

from snakebot.core import ffi, lib
from snakebot.formats.protocol import Instruction
from snakebot.sim.servo import motor
from snakebot.sim.servo.reference import MAX_STEP_S, ReferenceServo, Reply
from snakebot.sim.servo.registers import RegisterFile

_READ = int(Instruction.READ)
_UNITS = ffi.new(
    "sim_servo_units *",
    {
        "ticks_per_rev": motor.TICKS_PER_REV,
        "speed_unit": motor.SPEED_UNIT_RPM * motor.TICKS_PER_S_PER_RPM,
        "speed_unit_rpm": motor.SPEED_UNIT_RPM,
        "ticks_per_s_per_rpm": motor.TICKS_PER_S_PER_RPM,
        "load_step": float(motor._LOAD.scale.factor),
        "torque_full": motor.TORQUE_FULL,
        "ambient_c": motor.AMBIENT_C,
        "max_step_s": MAX_STEP_S,
        "direction_bit": motor.DIRECTION_BIT,
        "max_position": motor.MAX_POSITION,
    },
)
"""The unit facts the C needs, from the device description (through ``motor``)."""


def _field(name: str, convert: type) -> property:
    """A property kept in the C struct's field ``name`` (``convert``: what a value from
    outside, e.g. a numpy number from the physics world, is stored as)."""

    def put(self: VirtualServo, value: Any) -> None:
        setattr(self._c, name, convert(value))

    return property(attrgetter("_c." + name), put)


# attribute of the reference model -> (field of the C struct, type)
_FIELDS: dict[str, tuple[str, type]] = {
    "_stall": ("stall", float),
    "_moving_load": ("moving_load", float),
    "_stall_rise": ("stall_rise", float),
    "_thermal_tau": ("thermal_tau", float),
    "_goal_max": ("goal_max", int),
    "_speed_max": ("speed_max", int),
    "_goal": ("goal", int),
    "_moving_speed": ("moving_speed", int),
    "_torque_enable": ("torque_enable", int),
    "_torque_limit": ("torque_limit", int),
    "_cw_margin": ("cw_margin", int),
    "_ccw_margin": ("ccw_margin", int),
    "_cw_slope": ("cw_slope", int),
    "_ccw_slope": ("ccw_slope", int),
    "_punch": ("punch", int),
    "_cw_limit": ("cw_limit", int),
    "_ccw_limit": ("ccw_limit", int),
    "_temp_limit": ("temp_limit", int),
    "_shutdown": ("shutdown", int),
    "_srl": ("srl", int),
    "_id": ("id", int),
    "_speed_setting": ("speed_setting", float),
    "_vmax": ("vmax", float),
    "_vmax_wheel": ("vmax_wheel", float),
    "wheel_mode": ("wheel_mode", bool),
    "_voltage_bad": ("voltage_bad", bool),
    "ideal": ("ideal", bool),
    "world_driven": ("world_driven", bool),
    "powered": ("powered", bool),
    "t": ("t", float),
    "pos": ("pos", float),
    "vel": ("vel", float),
    "temp": ("temp", float),
    "load_fraction": ("load_fraction", float),
    "supply_v": ("supply_v", float),
    "external_torque": ("external_torque", float),
    "load_cw": ("load_cw", bool),
    "moving": ("moving", bool),
    "overload": ("overload", bool),
    "latched": ("latched", int),
}


class VirtualServo(ReferenceServo):
    """One emulated servo (see :class:`ReferenceServo` for what it does): the same
    model, its hot path in C."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._c = ffi.new("sim_servo *")
        self._c.units = _UNITS
        self._out = ffi.new("uint8_t[]", 256)
        self._controls = ffi.new("double[]", lib.SIM_SERVO_CONTROLLER)
        super().__init__(*args, **kwargs)

    @property
    def c_struct(self) -> Any:
        """The C struct holding this servo's state (``sim_servo *``)."""
        return self._c

    @property
    def regs(self) -> RegisterFile:
        """The control table (the C struct points into its bytes)."""
        return self._regs

    @regs.setter
    def regs(self, regs: RegisterFile) -> None:
        self._regs = regs
        # pins the bytearray's buffer: it can no longer be resized, and is never meant to
        self._image = ffi.from_buffer("uint8_t[]", regs.image)
        self._c.image = self._image
        self._c.size = regs.size

    def advance(self, t: float) -> None:
        lib.sim_servo_advance(self._c, t)

    def _refresh_present(self, first: int = 0, end: int = 1 << 16) -> None:
        lib.sim_servo_refresh_present(self._c, first, end)

    def _conditions(self) -> int:
        return lib.sim_servo_conditions(self._c)

    def _alarm(self, flags: int) -> None:
        lib.sim_servo_alarm(self._c, flags)

    def handle(self, target: int, code: int, params: bytes, t: float) -> Reply | None:
        c = self._c
        if code == _READ and target == c.id and c.powered and c.srl and len(params) == 2:
            n = lib.sim_servo_read(c, t, params[0], params[1], self._out, 256)
            if n:
                return ffi.buffer(self._out, n)[:], self.baudrate
        return super().handle(target, code, params, t)

    def _write_at(self, address: int, data: bytes, registered: bool) -> int:
        if not registered:
            flags = lib.sim_servo_write_goal(self._c, address, data, len(data))
            if flags >= 0:
                return flags
        return super()._write_at(address, data, registered)

    # -- a physics world's hooks, once per servo per control tick: in C, on the struct --

    def controller(self) -> tuple[float, ...]:
        lib.sim_servo_controller(self._c, self._controls)
        return tuple(self._controls)

    def set_motion(
        self,
        t: float,
        pos: float,
        vel: float,
        load_fraction: float,
        load_cw: bool,
        moving: bool,
        overload: bool,
    ) -> tuple[float, ...]:
        lib.sim_servo_set_motion(self._c, t, pos, vel, load_fraction, load_cw, moving, overload)
        return self.controller()

    def sync_write_block(self, address: int, data: bytes, t: float) -> None:
        if lib.sim_servo_sync_block(self._c, t, address, data, len(data)) < 0:
            super().sync_write_block(address, data, t)


for _name, (_member, _type) in _FIELDS.items():
    setattr(VirtualServo, _name, _field(_member, _type))
