"""A virtual AX-12A / AX-12W: its control table, its answers to Protocol 1.0, its motion.

What it does, as the ROBOTIS manuals describe (the choices they leave open are marked):

* PING, READ, WRITE, REG_WRITE + ACTION, SYNC_WRITE and RESET (factory defaults,
  ID 1, 1 Mbps; the status packet goes out first, from the old ID). BULK_READ is not an
  AX-12 instruction: unicast it gets the instruction error, broadcast nothing.
* Status Return Level: 0 answers PING only, 1 PING and READ, 2 everything; broadcast
  never answers; Return Delay Time (2 us units) is honoured by the bus.
* Error bits: RANGE for writes to read-only or reserved addresses, partial writes of a
  two-byte register, values out of range, writes other than Torque Enable..Torque Limit
  while locked, and READs past the end of the table; ANGLE_LIMIT for a goal outside
  the angle limits (the write is refused); INSTRUCTION for unknown instructions and
  ACTION with nothing registered; CHECKSUM (answered from the ID in the damaged packet)
  for a bad checksum; INPUT_VOLTAGE, OVERHEATING and OVERLOAD while those conditions hold.
* Alarm shutdown: an error whose bit is set in Shutdown drops Torque Limit to 0; the
  servo drives again only after Torque Limit is written (the error stays reported
  until then).
* Lock (1 until power is lost), wheel mode (both angle limits 0: Moving Speed 0-2047,
  bit 10 = CW), Max Torque copied to Torque Limit at power-on, and writing Goal
  Position switches the torque on (as real AX-12s do; the manuals do not say it).
* The reply to a WRITE that changes the ID comes from the new ID, and a reply to a
  WRITE that changes the baud rate still goes out at the old rate. The manuals do not
  say; this is the harsher reading (a firmware that builds the status packet after
  executing the write), so a client that copes here (send the write, then PING the
  new ID) also copes with a servo that answers from the old ID.

Motion and heat follow ``snakesim.motor``. ``ideal=True`` makes motion instant (the
position is the goal), for comparing the emulated world with a prediction exactly.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from snakebot.protocol import (
    BROADCAST_ID,
    ControlTable,
    ControlTableError,
    Entry,
    ErrorFlags,
    Instruction,
    Packet,
    Rejected,
    status,
)
from snakesim import motor
from snakesim.errors import SimOptionError
from snakesim.registers import RegisterFile

MAX_STEP_S = 0.02
"""Longest physics step: alarms (heat, overload) take effect within this much bus time."""

_PING = int(Instruction.PING)
_READ = int(Instruction.READ)
_WRITE = int(Instruction.WRITE)
_REG_WRITE = int(Instruction.REG_WRITE)
_ACTION = int(Instruction.ACTION)
_RESET = int(Instruction.RESET)
_SYNC_WRITE = int(Instruction.SYNC_WRITE)

_VOLTAGE = int(ErrorFlags.INPUT_VOLTAGE)
_ANGLE = int(ErrorFlags.ANGLE_LIMIT)
_HEAT = int(ErrorFlags.OVERHEATING)
_RANGE = int(ErrorFlags.RANGE)
_CHECKSUM = int(ErrorFlags.CHECKSUM)
_OVERLOAD = int(ErrorFlags.OVERLOAD)
_INSTRUCTION = int(ErrorFlags.INSTRUCTION)

Reply = tuple[bytes, float]
"""A status packet and the baud rate it is sent at."""

# Registers the physics reads on every step, mirrored in attributes ("shadows") that are
# refreshed whenever the register is written, so a step costs no table look-ups.
_SHADOWS = {
    "Goal Position": "_goal",
    "Moving Speed": "_moving_speed",
    "Torque Enable": "_torque_enable",
    "Torque Limit": "_torque_limit",
    "CW Compliance Margin": "_cw_margin",
    "CCW Compliance Margin": "_ccw_margin",
    "CW Angle Limit": "_cw_limit",
    "CCW Angle Limit": "_ccw_limit",
    "Temperature Limit": "_temp_limit",
    "Min Voltage Limit": "_min_voltage",
    "Max Voltage Limit": "_max_voltage",
    "Shutdown": "_shutdown",
    "Baud Rate": "_baud_reg",
    "Return Delay Time": "_return_delay_reg",
    "Status Return Level": "_srl",
    "Lock": "_lock",
    "ID": "_id",
}

_DERIVED_FROM = {
    "Baud Rate",
    "Return Delay Time",
    "CW Angle Limit",
    "CCW Angle Limit",
    "Moving Speed",
}


def baud_from_register(value: int) -> float:
    """Bits per second for a Baud Rate register value: 2 000 000 / (value + 1)."""
    return 2_000_000 / (value + 1)


class VirtualServo:
    """One emulated servo. The bus feeds it packets (:meth:`receive`) and asks it where it
    is (:meth:`advance`, :attr:`present_position`); times are bus seconds."""

    def __init__(
        self,
        servo_id: int = 1,
        model: str = "AX-12A",
        *,
        position: float = 512.0,
        ideal: bool = False,
        start_time: float = 0.0,
    ) -> None:
        try:
            self.table = ControlTable.for_model(model)
            self.spec = motor.spec_for(model)
        except (KeyError, ControlTableError):
            raise SimOptionError(f"unknown servo model {model!r}: use AX-12A or AX-12W") from None
        if not 0 <= servo_id <= 253:
            raise SimOptionError(f"servo ID must be 0..253, got {servo_id}")
        if not 0 <= position <= motor.MAX_POSITION:
            raise SimOptionError(f"start position must be 0..1023 ticks, got {position}")
        self.model = self.table.model
        self.regs = RegisterFile(self.table)
        self.ideal = ideal
        self.t = start_time
        self.powered = True
        self.supply_v = self.spec.nominal_voltage
        self.external_torque = 0.0
        """Torque the outside world applies, N m (+ turns toward larger positions)."""
        goal = self.regs.entry("Goal Position")
        self._goal_addr = goal.address
        self._goal_max = goal.max if goal.max is not None else 0xFFFF
        self.on_eeprom_change: Callable[[VirtualServo], None] | None = None
        self.on_link_change: Callable[[VirtualServo], None] | None = None
        """Called when what the bus needs to know changes: baud rate, power."""
        self.pos = float(position)
        self.vel = 0.0
        self.temp = motor.AMBIENT_C
        self.load_fraction = 0.0
        self.load_cw = False
        self.moving = False
        self.overload = False
        self.latched = 0
        self._pending: list[tuple[Entry, int]] | None = None
        self._vmax = self.spec.max_speed(self.supply_v)
        self._vmax_wheel = self.spec.max_speed(self.supply_v, wheel=True)
        self._shadow_all()
        self.regs.set("ID", servo_id)
        self._id = servo_id
        self._power_on_ram()

    # -- shadows --------------------------------------------------------------------------

    def _shadow_all(self) -> None:
        for name, attr in _SHADOWS.items():
            setattr(self, attr, self.regs.get(name))
        self._derive()

    def _derive(self) -> None:
        self.baudrate = baud_from_register(self._baud_reg)
        """The servo's UART rate in bits per second (from its Baud Rate register)."""
        self.return_delay_s = self._return_delay_reg * 2e-6
        """Return Delay Time in seconds (2 us per unit)."""
        self.wheel_mode = self._cw_limit == 0 and self._ccw_limit == 0
        self._speed_setting = motor.speed_setting(self._moving_speed)
        tenths = round(self.supply_v * 10)
        self._voltage_bad = not self._min_voltage <= tenths <= self._max_voltage

    def set_register(self, name: str, value: int) -> None:
        """Store ``value`` in register ``name`` directly, as a factory or a test would
        (no range check, no status packet), keeping the servo's view of it current."""
        old_baud = self.baudrate
        self.regs.set(name, value)
        self._shadow_all()
        if self.baudrate != old_baud:
            self._link_changed()

    # -- identity and settings ------------------------------------------------------------

    @property
    def id(self) -> int:
        return self._id

    @property
    def status_return_level(self) -> int:
        return self._srl

    @property
    def locked(self) -> bool:
        return self._lock == 1

    @property
    def present_position(self) -> int:
        """Present Position as the servo reports it (0-1023)."""
        p = round(self.pos)
        return 0 if p < 0 else (motor.MAX_POSITION if p > motor.MAX_POSITION else p)

    # -- power ----------------------------------------------------------------------------

    def _power_on_ram(self) -> None:
        defaults = self.table.default_image()
        end = self.table.eeprom_end
        self.regs.image[end:] = defaults[end:]
        self.regs.set("Goal Position", self.present_position)
        self.regs.set("Moving Speed", 0)
        self.regs.set("Torque Limit", self.regs.get("Max Torque"))
        self.latched = 0
        self._pending = None
        self.moving = False
        self.vel = 0.0
        self._shadow_all()
        self._refresh_present()

    def power_off(self, t: float) -> None:
        """Lose power at bus time ``t``: deaf, mute, limp; RAM is lost."""
        self.advance(t)
        self.powered = False
        self.vel = 0.0
        self.moving = False
        self._link_changed()

    def power_on(self, t: float) -> None:
        """Power returns at bus time ``t``: RAM back to power-on values, EEPROM kept."""
        self.advance(t)
        self.powered = True
        self._power_on_ram()
        self._link_changed()

    def set_supply(self, t: float, volts: float) -> None:
        """The supply voltage at this servo from bus time ``t`` on."""
        self.advance(t)
        self.supply_v = float(volts)
        self._vmax = self.spec.max_speed(self.supply_v)
        self._vmax_wheel = self.spec.max_speed(self.supply_v, wheel=True)
        self._derive()

    def _link_changed(self) -> None:
        if self.on_link_change is not None:
            self.on_link_change(self)

    # -- physics --------------------------------------------------------------------------

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

    def _step(self, dt: float) -> None:
        spec = self.spec
        if not self.powered:
            self.vel = 0.0
            self.moving = False
            self.overload = False
            self.load_fraction = 0.0
            self.temp = motor.thermal_step(self.temp, 0.0, dt, spec)
            return
        limit = self._torque_limit
        torque_on = self._torque_enable == 1 and limit > 0
        stall = spec.stall_torque_nm
        available = stall * limit / 1023.0
        load = self.external_torque
        if load < 0.0:
            load = -load
        overload = torque_on and load > available
        old = self.pos
        new = old
        moving = False
        if torque_on and not overload:
            scale = 1.0 - load / stall if load else 1.0
            if self.wheel_mode:
                value = self._moving_speed
                v = (value & 1023) / 1023.0 * self._vmax_wheel * scale
                if value & motor.DIRECTION_BIT:
                    v = -v
                new = (old + v * dt) % motor.TICKS_PER_REV
                moving = v != 0.0
            else:
                goal = self._goal
                if self.ideal:
                    new = float(goal)
                else:
                    low = goal - self._cw_margin
                    high = goal + self._ccw_margin
                    if old < low or old > high:
                        vmax = self._vmax * scale
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
        if self.wheel_mode and abs(delta) > motor.TICKS_PER_REV / 2:
            delta -= motor.TICKS_PER_REV if delta > 0 else -motor.TICKS_PER_REV
        self.vel = delta / dt
        self.moving = moving
        self.overload = overload
        if not torque_on:
            fraction = 0.0
        elif overload:
            fraction = available / stall
        else:
            fraction = load / stall + (spec.moving_load if delta else 0.0)
        self.load_fraction = fraction if fraction < 1.0 else 1.0
        self.load_cw = self.external_torque > 0 if self.external_torque else delta < 0
        temp = self.temp
        if fraction or temp != motor.AMBIENT_C:
            steady = motor.AMBIENT_C + spec.stall_rise_c * fraction * fraction
            temp = self.temp = steady + (temp - steady) * math.exp(-dt / spec.thermal_tau_s)
        if overload or self._voltage_bad or temp >= self._temp_limit + 0.5:
            conditions = self._conditions()
            if conditions & self._shutdown:
                self._alarm(conditions)

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

    def _refresh_present(self) -> None:
        regs = self.regs
        regs.set("Present Position", self.present_position)
        regs.set("Present Speed", motor.speed_register(self.vel))
        regs.set("Present Load", motor.load_register(self.load_fraction, self.load_cw))
        regs.set("Present Voltage", max(0, min(255, round(self.supply_v * 10))))
        regs.set("Present Temperature", max(0, min(255, round(self.temp))))
        regs.set("Moving", int(self.moving))

    @property
    def errors(self) -> ErrorFlags:
        """The error bits a status packet would carry now (conditions and latched alarms)."""
        return ErrorFlags(self._conditions() | self.latched)

    # -- Protocol 1.0 ---------------------------------------------------------------------

    def _answers(self, code: int) -> bool:
        if code == _PING:
            return True
        return self._srl >= (1 if code == _READ else 2)

    def receive(self, event: Packet | Rejected, t: float) -> Reply | None:
        """Handle one packet (or damaged packet) heard at bus time ``t``; return the
        status packet to send and its baud rate, or None."""
        if not self.powered:
            return None
        if isinstance(event, Rejected):
            return self._rejected(event, t)
        my_id = self._id
        target = event.id
        if target != my_id and target != BROADCAST_ID:
            return None
        self.advance(t)
        code = event.code
        params = event.params
        baud = self.baudrate
        data = b""
        if code == _SYNC_WRITE:
            self._sync_write(params, my_id)
            return None
        if code == _PING or code == _RESET:
            flags = 0
        elif code == _READ:
            flags, data = self._read(params)
        elif code == _WRITE:
            flags = self._write(params, registered=False)
        elif code == _REG_WRITE:
            flags = self._write(params, registered=True)
        elif code == _ACTION:
            if self._pending is None:
                flags = _INSTRUCTION
            else:
                flags = 0
                pending, self._pending = self._pending, None
                self._commit(pending)
                self.regs.set("Registered", 0)
        else:
            flags = _INSTRUCTION  # BULK_READ included: not an AX-12 instruction
        if flags:
            self._alarm(flags)
        reply = None
        if target != BROADCAST_ID and self._answers(code):
            error = flags | self._conditions() | self.latched
            reply = (status(self._id if code != _RESET else my_id, error, data), baud)
        if code == _RESET:
            self.factory_reset()
        return reply

    def _rejected(self, event: Rejected, t: float) -> Reply | None:
        data = event.data
        if event.reason != "checksum" or len(data) < 6 or data[2] != self._id:
            return None
        self.advance(t)
        self._alarm(_CHECKSUM)
        if not self._answers(data[4]):
            return None
        error = _CHECKSUM | self._conditions() | self.latched
        return status(self._id, error), self.baudrate

    def _read(self, params: bytes) -> tuple[int, bytes]:
        if len(params) != 2:
            return _RANGE, b""
        self._refresh_present()
        data = self.regs.read(params[0], params[1])
        if data is None:
            return _RANGE, b""
        return 0, data

    def _check(self, address: int, data: bytes) -> tuple[int, list[tuple[Entry, int]]]:
        flags, values = self.regs.check_write(address, data, locked=self._lock == 1)
        if flags:
            return flags, values
        cw, ccw = self._cw_limit, self._ccw_limit
        if len(values) > 1:
            for entry, value in values:
                if entry.name == "CW Angle Limit":
                    cw = value
                elif entry.name == "CCW Angle Limit":
                    ccw = value
        if cw or ccw:  # joint mode
            for entry, value in values:
                name = entry.name
                if name == "Goal Position" and not cw <= value <= ccw:
                    return _ANGLE, []
                if name == "Moving Speed" and value > 1023:
                    return _RANGE, []
        return 0, values

    def _write(self, params: bytes, *, registered: bool) -> int:
        if len(params) < 2:
            return _RANGE
        return self._write_at(params[0], params[1:], registered=registered)

    def _write_at(self, address: int, data: bytes, *, registered: bool) -> int:
        if address == self._goal_addr and len(data) == 2 and not registered:
            # The hot path (every SYNC_WRITE of goals), the same rules as below.
            value = data[0] | data[1] << 8
            if value > self._goal_max:
                return _RANGE
            if (self._cw_limit or self._ccw_limit) and not (
                self._cw_limit <= value <= self._ccw_limit
            ):
                return _ANGLE
            image = self.regs.image
            image[address] = data[0]
            image[address + 1] = data[1]
            self._goal = value
            if self._torque_enable != 1:
                self.regs.set("Torque Enable", 1)  # a goal switches the torque on
                self._torque_enable = 1
            return 0
        flags, values = self._check(address, data)
        if flags:
            return flags
        if registered:
            self._pending = values
            self.regs.set("Registered", 1)
        else:
            self._commit(values)
        return 0

    def _commit(self, values: list[tuple[Entry, int]]) -> None:
        regs = self.regs
        eeprom = derive = False
        for entry, value in values:
            name = entry.name
            if entry.area == "EEPROM" and regs.get(name) != value:
                eeprom = True
            regs.set(name, value)
            attr = _SHADOWS.get(name)
            if attr is not None:
                setattr(self, attr, value)
            if name == "Goal Position":
                if self._torque_enable != 1:
                    regs.set("Torque Enable", 1)  # a goal switches the torque on
                    self._torque_enable = 1
            elif name == "Torque Limit":
                self.latched = 0
            elif name in _DERIVED_FROM:
                derive = True
        if derive:
            old_baud = self.baudrate
            self._derive()
            if self.baudrate != old_baud:
                self._link_changed()
        if eeprom and self.on_eeprom_change is not None:
            self.on_eeprom_change(self)

    def _sync_write(self, params: bytes, my_id: int) -> None:
        if len(params) < 2:
            return
        address, length = params[0], params[1]
        block = length + 1
        n = len(params)
        if length == 0 or (n - 2) % block:
            return  # malformed: a real servo cannot find its slice either
        for i in range(2, n, block):
            if params[i] == my_id:
                flags = self._write_at(address, params[i + 1 : i + block], registered=False)
                if flags:
                    self._alarm(flags)
                return

    def factory_reset(self) -> None:
        """RESET: every register back to its factory value (ID 1, 1 Mbps), as at power-on."""
        old_baud = self.baudrate
        self.regs.image[:] = self.table.default_image()
        self._power_on_ram()
        if self.on_eeprom_change is not None:
            self.on_eeprom_change(self)
        if self.baudrate != old_baud:
            self._link_changed()

    def load_eeprom(self, data: bytes) -> None:
        """Restore a saved EEPROM image, then re-run the power-on RAM set-up."""
        old_baud = self.baudrate
        self.regs.load_eeprom(data)
        self._power_on_ram()
        if self.baudrate != old_baud:
            self._link_changed()
