"""The AX-12 as an actuator in the physics world: its position controller and its DC motor.

The controller works in position ticks, as the servo's registers do. Outside the
compliance margin it drives the motor with a duty that starts at Punch and rises over the
compliance slope to full; inside the margin it lets go. The duty is capped by Torque
Limit (the AX-12 limits the motor's drive, so Max Torque / Torque Limit scale the stall
torque) and by the Moving Speed setting (a duty that turns the unloaded motor at that
speed). Wheel mode drives the duty straight from Moving Speed.

The motor is a geared DC motor: at duty u and joint speed w its torque is

    tau = stall(V) * u - damping * w,    stall(V) = stall_nominal * V / V_nominal,
    damping = stall_nominal / no_load_speed_nominal

so the no-load speed scales with the supply voltage and the speed falls linearly with
load, to zero at the stall torque. The physics world applies the first term as a
force and the second as the joint's damping (MuJoCo integrates damping implicitly, which
keeps a stiff gear train stable at a coarse time step). The gear train's reflected rotor
inertia is the joint's armature. Stall torque and no-load speed are the servo model's
(``snakebot.sim.servo.motor.SPECS``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from snakebot.model.robots import TICKS_PER_RAD
from snakebot.sim.servo import motor

ARMATURE_KG_M2 = 0.002
"""Reflected inertia of the motor and gears at the output shaft (a model choice: the
AX-12's 254:1 train makes its tiny rotor weigh on the joint like a heavy link)."""

OVERLOAD_HOLD_S = 0.1
"""How long the controller must demand more drive than it is allowed (Torque Limit, or
Moving Speed's cap when it caps the drive), with the joint stalled, before the servo
reports overload."""

STALLED_FRACTION = 0.01
"""A joint slower than this fraction of the speed its capped drive turns the unloaded
motor at (Torque Limit's or Moving Speed's cap, at the supply voltage) counts as stalled:
a slow Moving Speed under ``speed_limit = "drive"`` moves a joint slowly, not stalls it,
and a joint that still moves its load, however slowly, holds it (`sim goto`'s snake5 to
seed 34's target in MuJoCo ends its loops creeping to their goals at 4.8 % of that speed,
the load taking 95 % of the drive; a joint pushed to its stop does not move at all)."""

DUTY_FULL = float(motor.TORQUE_FULL)
"""Torque Limit, Punch and wheel-mode Moving Speed at full duty (1023)."""

_DIRECTION_BIT = motor.DIRECTION_BIT
_LOW_BITS = _DIRECTION_BIT - 1


@dataclass(frozen=True)
class Actuator:
    """The motor constants of one servo model at the output shaft (SI units)."""

    stall_nm: float
    nominal_v: float
    no_load_rad_s: float

    @classmethod
    def for_model(cls, model: str) -> Actuator:
        """The actuator of a servo model ("AX-12A", "AX-12W")."""
        spec = motor.spec_for(model)
        return cls(spec.stall_torque_nm, spec.nominal_voltage, spec.no_load_rpm * math.pi / 30.0)

    @property
    def damping(self) -> float:
        """Back-EMF braking, N m s/rad: the slope of the torque-speed line."""
        return self.stall_nm / self.no_load_rad_s

    def stall_at(self, volts: float) -> float:
        """Stall torque at supply voltage ``volts``."""
        return self.stall_nm * max(0.0, volts) / self.nominal_v

    def drive(
        self, controller: tuple[float, ...], pos_ticks: float
    ) -> tuple[float, float, float, float, bool]:
        """The motor's drive as a linear law around the present state, from the servo's
        controller registers (``VirtualServo.controller()``) at position ``pos_ticks``:
        duty = ``gain`` * (``target`` - position) + ``bias`` (gain in 1/tick, target in
        ticks), limited to +-``cap``; and whether the cap cuts the duty the controller
        asks for now (Torque Limit or Moving Speed, whichever binds). Inside the
        compliance margin the gain and bias are 0. Positive duty turns toward larger ticks."""
        goal, speed, on, limit, cw_m, ccw_m, cw_s, ccw_s, punch, volts, wheel, raw = controller
        if not on:
            return 0.0, 0.0, 0.0, 0.0, False
        limit_cap = limit / DUTY_FULL
        if wheel:
            u = (int(raw) & _LOW_BITS) / DUTY_FULL
            u = -u if int(raw) & _DIRECTION_BIT else u
            return 0.0, 0.0, u, limit_cap, abs(u) > limit_cap
        error = goal - pos_ticks
        if error > ccw_m:
            side, margin, slope = 1.0, ccw_m, ccw_s
        elif error < -cw_m:
            side, margin, slope = -1.0, cw_m, cw_s
        else:
            return 0.0, 0.0, 0.0, 0.0, False
        base = punch / DUTY_FULL
        # duty = side * (base + (1 - base) * (|error| - margin) / slope), saturating at 1
        gain = (1.0 - base) / slope
        bias = side * (base - gain * margin)
        wanted = min(1.0, abs(gain * error + bias))
        # the speed setting: the duty that turns the unloaded motor at that speed
        no_load_ticks = self.no_load_rad_s * TICKS_PER_RAD * volts / self.nominal_v
        speed_cap = speed / no_load_ticks if no_load_ticks > 0 else 0.0
        cap = min(1.0, limit_cap, speed_cap)
        # a cap cuts when the controller asks for more than the drive allowed: Torque
        # Limit's or (speed_limit "drive") Moving Speed's, whichever binds; no supply, no cut
        return gain, goal, bias, cap, wanted > cap and no_load_ticks > 0
