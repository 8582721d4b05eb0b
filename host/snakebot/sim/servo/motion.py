"""The servo's body between packets: motion (``snakebot.sim.servo.motor``'s model, or a
physics world's report), heat, the alarms they raise (Shutdown cuts the torque), and the
present-state registers a READ sees refreshed from them."""

from __future__ import annotations

import math

from snakebot.formats.protocol import ErrorFlags
from snakebot.sim.servo import motor

MAX_STEP_S = 0.02
"""Longest physics step: alarms (heat, overload) take effect within this much bus time."""

_VOLTAGE = int(ErrorFlags.INPUT_VOLTAGE)
_HEAT = int(ErrorFlags.OVERHEATING)
_OVERLOAD = int(ErrorFlags.OVERLOAD)

_AMBIENT_C = motor.AMBIENT_C
_exp = math.exp


class ServoMotion:
    """Motion, heat and alarms (a part of
    :class:`~snakebot.sim.servo.reference.ReferenceServo`, working on the attributes it
    sets up)."""

    def advance(self, t: float) -> None:
        """Bring the physical state forward to bus time ``t``."""
        dt_total = t - self.t
        if dt_total <= 0.0:
            return
        while dt_total > MAX_STEP_S:
            self._step(MAX_STEP_S)
            dt_total -= MAX_STEP_S
        self._step(dt_total)
        self.t = t

    def set_external_torque(self, t: float, torque_nm: float) -> None:
        """From bus time ``t`` on, the outside world pushes with ``torque_nm``."""
        self.advance(t)
        self.external_torque = float(torque_nm)

    def controller(self) -> tuple[float, ...]:
        """What the servo's position controller works from, for a physics world:
        (goal, Moving Speed setting in ticks/s (inf: no limit), torque on (0/1), Torque
        Limit, CW margin, CCW margin, CW slope, CCW slope, Punch, supply volts, wheel mode
        (0/1), raw Moving Speed). Torque is off while unpowered."""
        on = 1.0 if self.powered and self._torque_enable == 1 and self._torque_limit > 0 else 0.0
        return (
            float(self._goal),
            self._speed_setting,
            on,
            float(self._torque_limit),
            float(self._cw_margin),
            float(self._ccw_margin),
            float(self._cw_slope),
            float(self._ccw_slope),
            float(self._punch),
            self.supply_v,
            1.0 if self.wheel_mode else 0.0,
            float(self._moving_speed),
        )

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
        """A physics world's report at bus time ``t``: position (ticks), speed (ticks/s),
        load (fraction of stall torque, ``load_cw``: pushing toward smaller positions),
        whether it moves, whether the load exceeds what it may give. Heat and alarms
        follow from them as for the servo's own motion. Returns :meth:`controller` as it
        is then (what the world drives the joint with next: one call per servo and tick)."""
        self.world_driven = True
        self.advance(t)
        self.pos = pos
        self.vel = vel
        self.load_fraction = load_fraction if load_fraction < 1.0 else 1.0
        self.load_cw = load_cw
        self.moving = moving
        self.overload = overload and self.powered
        if self.overload:
            conditions = self._conditions()
            if conditions & self._shutdown:
                self._alarm(conditions)
        return self.controller()

    def _heat(self, fraction: float, dt: float) -> None:
        temp = self.temp
        if fraction or temp != _AMBIENT_C:
            steady = _AMBIENT_C + self._stall_rise * fraction * fraction
            temp = self.temp = steady + (temp - steady) * _exp(-dt / self._thermal_tau)
        if self.overload or self._voltage_bad or temp >= self._temp_limit + 0.5:
            conditions = self._conditions()
            if conditions & self._shutdown:
                self._alarm(conditions)

    def _step(self, dt: float) -> None:
        if self.world_driven:  # the world set the motion; heat and alarms stay ours
            if self.powered:
                self._heat(self.load_fraction, dt)
            else:
                self.temp = motor.thermal_step(self.temp, 0.0, dt, self.spec)
            return
        if not self.powered:
            self.vel = 0.0
            self.moving = False
            self.overload = False
            self.load_fraction = 0.0
            self.temp = motor.thermal_step(self.temp, 0.0, dt, self.spec)
            return
        limit = self._torque_limit
        torque_on = self._torque_enable == 1 and limit > 0
        external = self.external_torque
        if external:
            stall = self._stall
            available = stall * limit / motor.TORQUE_FULL
            load = -external if external < 0.0 else external
            overload = torque_on and load > available
            scale = 1.0 - load / stall
        else:  # the same numbers with no load: nothing to scale by, no overload
            load = available = scale = 0.0
            overload = False
        old = self.pos
        new = old
        moving = False
        wheel = self.wheel_mode
        if torque_on and not overload:
            if wheel:
                value = self._moving_speed
                v = (value & motor.SPEED_MAX) / motor.SPEED_MAX * self._vmax_wheel
                if external:
                    v *= scale
                if value & motor.DIRECTION_BIT:
                    v = -v
                new = (old + v * dt) % motor.TICKS_PER_REV
                moving = v != 0.0
            elif self.ideal:
                new = float(self._goal)
            else:
                goal = self._goal
                low = goal - self._cw_margin
                high = goal + self._ccw_margin
                if old < low or old > high:
                    vmax = self._vmax * scale if external else self._vmax
                    speed = self._speed_setting
                    step = (vmax if speed > vmax else speed) * dt
                    if old < low:
                        new = old + step
                        if new >= low:
                            new = float(low)
                    else:
                        new = old - step
                        if new <= high:
                            new = float(high)
                    moving = not low <= new <= high
        self.pos = new
        delta = new - old
        if wheel and abs(delta) > motor.TICKS_PER_REV / 2:
            delta -= motor.TICKS_PER_REV if delta > 0 else -motor.TICKS_PER_REV
        self.vel = delta / dt
        self.moving = moving
        self.overload = overload
        if not torque_on:
            fraction = 0.0
        elif overload:
            fraction = available / self._stall
        elif external:
            fraction = load / self._stall + (self._moving_load if delta else 0.0)
        else:
            fraction = self._moving_load if delta else 0.0
        self.load_fraction = fraction if fraction < 1.0 else 1.0
        self.load_cw = external > 0 if external else delta < 0
        self._heat(fraction, dt)

    def _conditions(self) -> int:
        flags = _VOLTAGE if self._voltage_bad else 0
        if round(self.temp) > self._temp_limit:
            flags |= _HEAT
        if self.overload:
            flags |= _OVERLOAD
        return flags

    def _alarm(self, flags: int) -> None:
        """Errors in the Shutdown mask cut the torque (Torque Limit = 0) and stay reported."""
        shut = flags & self._shutdown
        if shut:
            self.regs.set("Torque Limit", 0)
            self._torque_limit = 0
            self.latched |= shut
            self.overload = False

    def _refresh_present(self, first: int = 0, end: int = 1 << 16) -> None:
        """Bring the present-state registers that overlap addresses ``first``..``end - 1``
        (default: all of them) up to date from the physics; a READ refreshes only what
        it reads."""
        image = self.regs.image
        position, speed, load, voltage, temperature, moving = self._present_addr
        if first < position + 2 and position < end:
            value = self.present_position
            image[position] = value & 0xFF
            image[position + 1] = value >> 8
        if first < speed + 2 and speed < end:
            value = motor.speed_register(self.vel)
            image[speed] = value & 0xFF
            image[speed + 1] = value >> 8
        if first < load + 2 and load < end:
            value = motor.load_register(self.load_fraction, self.load_cw)
            image[load] = value & 0xFF
            image[load + 1] = value >> 8
        if first <= voltage < end:
            image[voltage] = max(0, min(255, round(self.supply_v * 10)))
        if first <= temperature < end:
            image[temperature] = max(0, min(255, round(self.temp)))
        if first <= moving < end:
            image[moving] = int(self.moving)

    @property
    def errors(self) -> ErrorFlags:
        """The error bits a status packet would carry now (conditions and latched alarms)."""
        return ErrorFlags(self._conditions() | self.latched)
