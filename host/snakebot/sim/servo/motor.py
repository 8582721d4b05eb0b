"""The physics of one AX-12 actuator: how fast it can turn, what load it feels, how hot
it gets. Plain numbers and pure functions; the servo (``snakebot.sim.servo.reference``)
applies them.

Model, deliberately simple and stated here so nobody mistakes it for more:

* Motion is at constant speed toward the goal (no acceleration, no compliance slope,
  no punch), stopping as soon as the position enters the compliance margin around the
  goal. The speed is the Moving Speed register (0 = the model's no-load maximum),
  capped by a DC motor's linear torque-speed line: the no-load speed scales with the
  supply voltage and falls to 0 at the stall torque.
* An external torque (set by the world, or by a test to simulate overload) loads the
  motor; if it exceeds the torque the motor may give (stall torque x Torque Limit / 1023),
  the servo stalls and reports overload.
* Temperature is a first-order thermal model: it relaxes toward ambient plus a rise
  proportional to the square of the load (copper losses), with one time constant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, TypeVar

from snakebot.facts import devices

Power = TypeVar("Power", float, Any)
"""A float, or a numpy array of them (this module does not import numpy)."""

# The AX-12's units, from its device description (the family shares them).
_AX12 = devices.ax12()
_POSITION = _AX12.require_position()
_SPEED = _AX12.register("Present Speed")
_LOAD = _AX12.register("Present Load")
assert _SPEED.scale is not None and _SPEED.encoding.direction_bit is not None

POSITION_RANGE_DEG = _POSITION.span_deg
MAX_POSITION = _POSITION.range[1]
TICKS_PER_DEG = _POSITION.scale.per_unit("deg")
TICKS_PER_REV = 360.0 * TICKS_PER_DEG
"""A full turn in position ticks (the 300-360 degree dead zone included): 1227.6."""
TICKS_PER_S_PER_RPM = devices.conversion("rpm", "deg/s") * TICKS_PER_DEG
"""1 rpm = 6 degrees/s = 20.46 ticks/s."""
SPEED_UNIT_RPM = _SPEED.scale.factor_in("rpm")
"""Moving Speed and Present Speed unit."""
DIRECTION_BIT = 1 << _SPEED.encoding.direction_bit
"""The direction bit of speed and load values: set = CW (toward smaller positions)."""
SPEED_MAX = DIRECTION_BIT - 1
"""The largest speed magnitude (and joint-mode Moving Speed)."""
TORQUE_FULL = _AX12.register("Torque Limit").value_range()[1]
"""Torque Limit (and load magnitude) at the full stall torque."""
AMBIENT_C = 25.0


@dataclass(frozen=True)
class MotorSpec:
    """Physical constants of one servo model (ROBOTIS e-Manual figures at 12 V)."""

    model: str
    stall_torque_nm: float
    no_load_rpm: float
    wheel_no_load_rpm: float
    nominal_voltage: float = 12.0
    thermal_tau_s: float = 120.0
    stall_rise_c: float = 100.0
    moving_load: float = 0.05
    """Load (fraction of stall) the gear train takes while turning freely."""

    @property
    def no_load_rad_s(self) -> float:
        """Joint-mode no-load speed at the output shaft, rad/s, at the nominal voltage."""
        return self.no_load_rpm * math.pi / 30.0

    def electrical_power_w(self, torque_nm: Power, speed_rad_s: Power) -> Power:
        """The power the motor draws to give ``torque_nm`` at ``speed_rad_s`` (output
        shaft), from the DC motor model that stall torque and no-load speed at the
        nominal voltage fix: the torque constant at the shaft k = V / w0, the winding
        resistance R = V^2 / (stall w0), so P = R (tau / k)^2 + tau w = tau^2 w0 / stall
        + tau w (copper loss plus mechanical power). Never negative: the servo's driver
        does not give braking energy back to the supply. Plain floats (the physics world
        calls it for every joint at every step) or numpy arrays of them (a search's whole
        run at once)."""
        tau = torque_nm
        power = tau * tau * self.no_load_rad_s / self.stall_torque_nm + tau * speed_rad_s
        if type(power) is float:
            return power if power > 0.0 else 0.0
        return power * (power > 0.0)  # elementwise, an array's negative entries to 0

    def max_speed(self, voltage: float, wheel: bool = False) -> float:
        """No-load speed in ticks/s at ``voltage``."""
        rpm = self.wheel_no_load_rpm if wheel else self.no_load_rpm
        return rpm * TICKS_PER_S_PER_RPM * max(0.0, voltage) / self.nominal_voltage


SPECS: dict[str, MotorSpec] = {
    # AX-12A: 254:1, 1.5 N m stall, 59 rpm no load at 12 V.
    "AX-12A": MotorSpec("AX-12A", stall_torque_nm=1.5, no_load_rpm=59.0, wheel_no_load_rpm=59.0),
    # AX-12W: 32:1, 0.2 N m stall, 54 rpm in joint mode, 470 rpm in wheel mode.
    "AX-12W": MotorSpec("AX-12W", stall_torque_nm=0.2, no_load_rpm=54.0, wheel_no_load_rpm=470.0),
}


def spec_for(model: str) -> MotorSpec:
    """The physical constants of ``model`` ("AX-12A" or "AX-12W", any case)."""
    for name, spec in SPECS.items():
        if name.lower() == model.strip().lower():
            return spec
    raise KeyError(model)


def speed_setting(moving_speed: int) -> float:
    """Ticks/s for a joint-mode Moving Speed value (0 means "as fast as it can": inf)."""
    value = moving_speed & (DIRECTION_BIT - 1)
    return math.inf if value == 0 else value * SPEED_UNIT_RPM * TICKS_PER_S_PER_RPM


def speed_register(ticks_per_s: float) -> int:
    """Present Speed encoding of a signed speed (ticks/s; negative = CW)."""
    magnitude = min(SPEED_MAX, round(abs(ticks_per_s) / (SPEED_UNIT_RPM * TICKS_PER_S_PER_RPM)))
    return _SPEED.raw(-magnitude if ticks_per_s < 0 else magnitude)


def load_register(fraction: float, cw: bool) -> int:
    """Present Load encoding of a fraction of the stall torque, pushing CW or CCW."""
    magnitude = min(SPEED_MAX, abs(_LOAD.from_units(100.0 * fraction)))
    return _LOAD.raw(-magnitude if cw else magnitude)


def thermal_step(temp_c: float, load_fraction: float, dt: float, spec: MotorSpec) -> float:
    """Temperature after ``dt`` seconds at a constant load (exact for the model)."""
    steady = AMBIENT_C + spec.stall_rise_c * load_fraction * load_fraction
    return steady + (temp_c - steady) * math.exp(-dt / spec.thermal_tau_s)
