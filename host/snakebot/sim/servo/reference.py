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

Motion and heat follow ``snakebot.sim.servo.motor``. ``ideal=True`` makes motion instant (the
position is the goal), for comparing the emulated world with a prediction exactly.
A physics world may own the motion instead (``world_driven``): it reads the controller's
registers (:meth:`VirtualServo.controller`) and reports position, speed and load back
(:meth:`VirtualServo.set_motion`); the servo keeps its heat, alarms and protocol.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from snakebot.facts import devices
from snakebot.formats.protocol import (
    BROADCAST_ID,
    ControlTable,
    ControlTableError,
    Entry,
    ErrorFlags,
    Instruction,
    Packet,
    Rejected,
)
from snakebot.formats.protocol.instructions import HEADER as _HEADER
from snakebot.formats.protocol.instructions import frame
from snakebot.sim.errors import SimOptionError
from snakebot.sim.servo import motor
from snakebot.sim.servo.registers import RegisterFile

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
    "CW Compliance Slope": "_cw_slope",
    "CCW Compliance Slope": "_ccw_slope",
    "Punch": "_punch",
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

# The registers a READ sees refreshed from the physics (the three two-byte ones first).
_PRESENT = (
    "Present Position",
    "Present Speed",
    "Present Load",
    "Present Voltage",
    "Present Temperature",
    "Moving",
)

# Registers that what _derive computes depends on (link timing, wheel mode, the voltage
# alarm); Moving Speed, the most written, only changes the speed setting.
_DERIVED_FROM = {
    "Baud Rate",
    "Return Delay Time",
    "CW Angle Limit",
    "CCW Angle Limit",
    "Min Voltage Limit",
    "Max Voltage Limit",
}


class _WritePlan:
    """How a write of one length at one address lands in the control table, worked out
    once per shape: per register its offset in the data, width and range (``fields``);
    the shadows it refreshes (attribute, index of the value); the indexes of the
    registers the servo checks itself (-1: not in this write); and what it sets off."""

    __slots__ = (
        "address",
        "fields",
        "shadows",
        "goal",
        "speed",
        "cw",
        "ccw",
        "eeprom_bytes",
        "clears_alarms",
        "derive",
        "relinks",
    )

    def __init__(self, regs: RegisterFile, address: int, entries: tuple[Entry, ...]) -> None:
        self.address = address
        self.fields = tuple(
            (e.address - address, e.size == 2, *regs.value_range(e)) for e in entries
        )
        self.shadows = tuple(
            (_SHADOWS[e.name], i) for i, e in enumerate(entries) if e.name in _SHADOWS
        )
        names = [e.name for e in entries]

        def index(name: str) -> int:
            return names.index(name) if name in names else -1

        self.goal = index("Goal Position")
        self.speed = index("Moving Speed")
        # a write of one register alone checks against the limits already stored
        self.cw = index("CW Angle Limit") if len(entries) > 1 else -1
        self.ccw = index("CCW Angle Limit") if len(entries) > 1 else -1
        self.eeprom_bytes = sum(e.size for e in entries if e.area == "EEPROM")
        """How many of the written bytes are EEPROM (they come first)."""
        self.clears_alarms = "Torque Limit" in names
        self.derive = any(name in _DERIVED_FROM for name in names)
        self.relinks = "ID" in names or "Baud Rate" in names
        """Whether the write may change what the bus knows the servo by."""


_BAD_WRITE = _WritePlan.__new__(_WritePlan)
"""The plan of a write the table refuses (RANGE)."""


_AMBIENT_C = motor.AMBIENT_C
_exp = math.exp

_SPEED_SETTINGS = tuple(motor.speed_setting(value) for value in range(motor.DIRECTION_BIT))
"""``motor.speed_setting`` of every Moving Speed magnitude (the value's low ten bits, all
the setting depends on), worked out once."""


_BAUD = devices.ax12().require_baud()


def baud_from_register(value: int) -> float:
    """Bits per second for a Baud Rate register value (the AX-12's baud formula)."""
    return _BAUD.rate(value)


def sync_write_shape(params: bytes) -> tuple[int, int] | None:
    """(start address, bytes per servo block: ID + data) of SYNC_WRITE parameters, or
    None when they cannot be split into whole blocks."""
    if len(params) < 2:
        return None
    address, length = params[0], params[1]
    if length == 0 or (len(params) - 2) % (length + 1):
        return None
    return address, length + 1


class ReferenceServo:
    """One emulated servo, all in Python: the reference model. The bus feeds it packets
    (:meth:`receive`) and asks it where it is (:meth:`advance`,
    :attr:`present_position`); times are bus seconds. :class:`VirtualServo`, what the
    emulator uses, behaves the same with its hot path in C."""

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
        self._size = self.table.size
        self.ideal = ideal
        self.t = start_time
        self.powered = True
        self.supply_v = self.spec.nominal_voltage
        self.external_torque = 0.0
        """Torque the outside world applies, N m (+ turns toward larger positions)."""
        self.world_driven = False
        """True while a physics world owns the motion (see :meth:`set_motion`)."""
        regs = self.regs
        goal, speed = regs.entry("Goal Position"), regs.entry("Moving Speed")
        self._goal_addr = goal.address
        self._goal_max = regs.value_range(goal)[1]
        self._speed_max = regs.value_range(speed)[1]
        # what the hot path in _write_at takes for granted
        assert regs.value_range(goal)[0] == regs.value_range(speed)[0] == 0
        for locked in (False, True):
            assert regs.layout(goal.address, 4, locked) == (goal, speed), "control table changed"
        present = [self.regs.entry(name) for name in _PRESENT]
        assert [e.size for e in present] == [2, 2, 2, 1, 1, 1], "control table changed"
        self._present_addr = tuple(e.address for e in present)
        spec = self.spec
        self._stall = spec.stall_torque_nm
        self._moving_load = spec.moving_load
        self._stall_rise = spec.stall_rise_c
        self._thermal_tau = spec.thermal_tau_s
        self.on_eeprom_change: Callable[[ReferenceServo], None] | None = None
        self.on_link_change: Callable[[ReferenceServo], None] | None = None
        """Called when what the bus needs to know changes: baud rate, power, ID."""
        self.pos = float(position)
        self.vel = 0.0
        self.temp = motor.AMBIENT_C
        self.load_fraction = 0.0
        self.load_cw = False
        self.moving = False
        self.overload = False
        self.latched = 0
        self._pending: tuple[_WritePlan, bytes, list[int]] | None = None
        self._plans: dict[int, _WritePlan] = {}
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
        self._speed_setting = _SPEED_SETTINGS[self._moving_speed & motor.SPEED_MAX]
        tenths = round(self.supply_v * 10)
        self._voltage_bad = not self._min_voltage <= tenths <= self._max_voltage

    def set_register(self, name: str, value: int) -> None:
        """Store ``value`` in register ``name`` directly, as a factory or a test would
        (no range check, no status packet), keeping the servo's view of it current."""
        link = self.baudrate, self._id
        self.regs.set(name, value)
        self._shadow_all()
        if (self.baudrate, self._id) != link:
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
    ) -> None:
        """A physics world's report at bus time ``t``: position (ticks), speed (ticks/s),
        load (fraction of stall torque, ``load_cw``: pushing toward smaller positions),
        whether it moves, whether the load exceeds what it may give. Heat and alarms
        follow from them as for the servo's own motion."""
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
        return self.handle(event.id, event.code, event.params, t)

    def handle(self, target: int, code: int, params: bytes, t: float) -> Reply | None:
        """:meth:`receive` of a good packet given by its fields (the bus's whole-packet
        path, which checks the frame itself and builds no :class:`Packet`)."""
        if not self.powered:
            return None
        my_id = self._id
        if target != my_id and target != BROADCAST_ID:
            return None
        if t > self.t:
            self.advance(t)
        baud = self.baudrate
        if code == _READ and target != BROADCAST_ID and self._srl and len(params) == 2:
            # The hot path (every telemetry READ): as below, with the status packet
            # built here; a READ leaves no error of its own to latch when it succeeds.
            address, length = params[0], params[1]
            self._refresh_present(address, address + length)
            if 0 < length and address + length <= self._size:
                body = (
                    bytes((my_id, length + 2, self._conditions() | self.latched))
                    + self.regs.image[address : address + length]
                )
                return _HEADER + body + bytes((~sum(body) & 0xFF,)), baud
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
                (plan, staged, values), self._pending = self._pending, None
                self._commit(plan, staged, values)
                self.regs.set("Registered", 0)
        else:
            flags = _INSTRUCTION  # BULK_READ included: not an AX-12 instruction
        if flags:
            self._alarm(flags)
        reply = None
        if target != BROADCAST_ID and self._answers(code):
            error = flags | self._conditions() | self.latched
            reply = (frame(self._id if code != _RESET else my_id, error, data), baud)
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
        return frame(self._id, error), self.baudrate

    def _read(self, params: bytes) -> tuple[int, bytes]:
        if len(params) != 2:
            return _RANGE, b""
        address, length = params[0], params[1]
        self._refresh_present(address, address + length)
        data = self.regs.read(address, length)
        if data is None:
            return _RANGE, b""
        return 0, data

    def _plan(self, address: int, length: int) -> _WritePlan:
        """The plan of a write of ``length`` bytes at ``address`` in the present Lock
        state, cached under ``address << 9 | length << 1 | locked``."""
        locked = self._lock == 1
        key = address << 9 | length << 1 | locked
        plan = self._plans.get(key)
        if plan is None:
            entries = self.regs.layout(address, length, locked)
            plan = _BAD_WRITE if entries is None else _WritePlan(self.regs, address, entries)
            self._plans[key] = plan
        return plan

    def _write(self, params: bytes, *, registered: bool) -> int:
        if len(params) < 2:
            return _RANGE
        return self._write_at(params[0], params[1:], registered)

    def _write_at(self, address: int, data: bytes, registered: bool) -> int:
        """Check a write (the table's rules, ``RegisterFile.check_write``, then the
        servo's own: in joint mode a goal within the angle limits, those this write sets
        if it sets both registers or more, and Moving Speed at most 1023), then store it
        or, ``registered``, stage it for ACTION; return the error bits."""
        n = len(data)
        if address == self._goal_addr and (n == 2 or n == 4) and not registered:
            # The hot path (every SYNC_WRITE of goals, with or without Moving Speed):
            # the same rules and effects as the general path below.
            goal = data[0] | data[1] << 8
            speed = data[2] | data[3] << 8 if n == 4 else 0
            if goal > self._goal_max or speed > self._speed_max:
                return _RANGE
            cw, ccw = self._cw_limit, self._ccw_limit
            if cw or ccw:  # joint mode
                if not cw <= goal <= ccw:
                    return _ANGLE
                if speed > motor.SPEED_MAX:
                    return _RANGE
            self.regs.image[address : address + n] = data
            self._goal = goal
            if n == 4:
                self._moving_speed = speed
                self._speed_setting = _SPEED_SETTINGS[speed & motor.SPEED_MAX]
            if self._torque_enable != 1:
                self.regs.set("Torque Enable", 1)  # a goal switches the torque on
                self._torque_enable = 1
            return 0
        plan = self._plans.get(address << 9 | len(data) << 1 | (self._lock == 1))
        if plan is None:
            plan = self._plan(address, len(data))
        if plan is _BAD_WRITE:
            return _RANGE
        values = []
        for offset, wide, low, high in plan.fields:
            value = data[offset] | data[offset + 1] << 8 if wide else data[offset]
            if not low <= value <= high:
                return _RANGE
            values.append(value)
        goal, speed = plan.goal, plan.speed
        if goal >= 0 or speed >= 0:
            cw = self._cw_limit if plan.cw < 0 else values[plan.cw]
            ccw = self._ccw_limit if plan.ccw < 0 else values[plan.ccw]
            if cw or ccw:  # joint mode
                if goal >= 0 and not cw <= values[goal] <= ccw:
                    return _ANGLE
                if speed >= 0 and values[speed] > motor.SPEED_MAX:
                    return _RANGE
        if registered:
            self._pending = (plan, data, values)
            self.regs.set("Registered", 1)
        else:
            self._commit(plan, data, values)
        return 0

    def _commit(self, plan: _WritePlan, data: bytes, values: list[int]) -> None:
        """Store checked ``data`` (``values``: the registers it holds, in address order)
        and do what the registers written set off."""
        image = self.regs.image
        start = plan.address
        link = (self.baudrate, self._id) if plan.relinks else None
        n = plan.eeprom_bytes
        eeprom = n > 0 and image[start : start + n] != data[:n]
        image[start : start + len(data)] = data
        for attr, i in plan.shadows:
            setattr(self, attr, values[i])
        if plan.goal >= 0 and self._torque_enable != 1:
            self.regs.set("Torque Enable", 1)  # a goal switches the torque on
            self._torque_enable = 1
        if plan.clears_alarms:
            self.latched = 0
        if plan.derive:
            self._derive()
        elif plan.speed >= 0:  # all that _derive would change
            self._speed_setting = _SPEED_SETTINGS[self._moving_speed & motor.SPEED_MAX]
        if link is not None and (self.baudrate, self._id) != link:
            self._link_changed()
        if eeprom and self.on_eeprom_change is not None:
            self.on_eeprom_change(self)

    def _sync_write(self, params: bytes, my_id: int) -> None:
        shape = sync_write_shape(params)
        if shape is None:
            return  # malformed: a real servo cannot find its slice either
        address, block = shape
        k = params[2::block].find(my_id)  # the first block that names this servo
        if k >= 0:
            i = 2 + k * block
            self._write_block(address, params[i + 1 : i + block])

    def _write_block(self, address: int, data: bytes) -> None:
        flags = self._write_at(address, data, False)
        if flags:
            self._alarm(flags)

    def sync_write_block(self, address: int, data: bytes, t: float) -> None:
        """This servo's block of a broadcast SYNC_WRITE heard at bus time ``t`` (the bus
        parses the packet once and hands each servo named in it its own block)."""
        if self.powered:
            self.advance(t)
            self._write_block(address, data)

    def factory_reset(self) -> None:
        """RESET: every register back to its factory value (ID 1, 1 Mbps), as at power-on."""
        link = self.baudrate, self._id
        self.regs.image[:] = self.table.default_image()
        self._power_on_ram()
        if self.on_eeprom_change is not None:
            self.on_eeprom_change(self)
        if (self.baudrate, self._id) != link:
            self._link_changed()

    def load_eeprom(self, data: bytes) -> None:
        """Restore a saved EEPROM image, then re-run the power-on RAM set-up."""
        link = self.baudrate, self._id
        self.regs.load_eeprom(data)
        self._power_on_ram()
        if (self.baudrate, self._id) != link:
            self._link_changed()
