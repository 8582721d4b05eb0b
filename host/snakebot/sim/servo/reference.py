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

The servo is one class made of parts: its body between packets (``motion``) and its
handling of Protocol 1.0 (``packets``); this module sets it up and holds its identity,
its registers' shadows and its power.
"""

from __future__ import annotations

from collections.abc import Callable

from snakebot.errors import quoted
from snakebot.facts import devices
from snakebot.formats.protocol import ControlTable, ControlTableError
from snakebot.sim.errors import SimOptionError
from snakebot.sim.servo import motor
from snakebot.sim.servo.motion import MAX_STEP_S, ServoMotion
from snakebot.sim.servo.packets import (
    SHADOWS,
    SPEED_SETTINGS,
    Reply,
    ServoPackets,
    WritePlan,
    sync_write_shape,
)
from snakebot.sim.servo.registers import RegisterFile

__all__ = [
    "MAX_STEP_S",
    "ReferenceServo",
    "Reply",
    "baud_from_register",
    "sync_write_shape",
]

# The registers a READ sees refreshed from the physics (the three two-byte ones first).
_PRESENT = (
    "Present Position",
    "Present Speed",
    "Present Load",
    "Present Voltage",
    "Present Temperature",
    "Moving",
)

_BAUD = devices.ax12().require_baud()


def baud_from_register(value: int) -> float:
    """Bits per second for a Baud Rate register value (the AX-12's baud formula)."""
    return _BAUD.rate(value)


class ReferenceServo(ServoPackets, ServoMotion):
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
            raise SimOptionError(
                f"unknown servo model {quoted(model)}: use AX-12A or AX-12W"
            ) from None
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
        self._pending: tuple[WritePlan, bytes, list[int]] | None = None
        self._plans: dict[int, WritePlan] = {}
        self._vmax = self.spec.max_speed(self.supply_v)
        self._vmax_wheel = self.spec.max_speed(self.supply_v, wheel=True)
        self._shadow_all()
        self.regs.set("ID", servo_id)
        self._id = servo_id
        self._power_on_ram()

    # -- shadows --------------------------------------------------------------------------

    def _shadow_all(self) -> None:
        for name, attr in SHADOWS.items():
            setattr(self, attr, self.regs.get(name))
        self._derive()

    def _derive(self) -> None:
        self.baudrate = baud_from_register(self._baud_reg)
        """The servo's UART rate in bits per second (from its Baud Rate register)."""
        self.return_delay_s = self._return_delay_reg * 2e-6
        """Return Delay Time in seconds (2 us per unit)."""
        self.wheel_mode = self._cw_limit == 0 and self._ccw_limit == 0
        self._speed_setting = SPEED_SETTINGS[self._moving_speed & motor.SPEED_MAX]
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
