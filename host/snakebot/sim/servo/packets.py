"""Protocol 1.0 as the servo handles it: PING, READ, WRITE, REG_WRITE + ACTION,
SYNC_WRITE and RESET, their error bits and status packets; each write's shape worked out
once (:class:`WritePlan`: the registers it lands in, their ranges, the shadows it
refreshes and what it sets off), and the hot paths (a telemetry READ, a write of the
goal and speed) taken in a few steps with the same outcome."""

from __future__ import annotations

from snakebot.formats.protocol import (
    BROADCAST_ID,
    Entry,
    ErrorFlags,
    Instruction,
    Packet,
    Rejected,
)
from snakebot.formats.protocol.instructions import HEADER as _HEADER
from snakebot.formats.protocol.instructions import frame
from snakebot.sim.servo import motor
from snakebot.sim.servo.registers import RegisterFile

_PING = int(Instruction.PING)
_READ = int(Instruction.READ)
_WRITE = int(Instruction.WRITE)
_REG_WRITE = int(Instruction.REG_WRITE)
_ACTION = int(Instruction.ACTION)
_RESET = int(Instruction.RESET)
_SYNC_WRITE = int(Instruction.SYNC_WRITE)

_ANGLE = int(ErrorFlags.ANGLE_LIMIT)
_RANGE = int(ErrorFlags.RANGE)
_CHECKSUM = int(ErrorFlags.CHECKSUM)
_INSTRUCTION = int(ErrorFlags.INSTRUCTION)

Reply = tuple[bytes, float]
"""A status packet and the baud rate it is sent at."""

# Registers the physics reads on every step, mirrored in attributes ("shadows") that are
# refreshed whenever the register is written, so a step costs no table look-ups.
SHADOWS = {
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


class WritePlan:
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
            (SHADOWS[e.name], i) for i, e in enumerate(entries) if e.name in SHADOWS
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


_BAD_WRITE = WritePlan.__new__(WritePlan)
"""The plan of a write the table refuses (RANGE)."""


SPEED_SETTINGS = tuple(motor.speed_setting(value) for value in range(motor.DIRECTION_BIT))
"""``motor.speed_setting`` of every Moving Speed magnitude (the value's low ten bits, all
the setting depends on), worked out once."""


def sync_write_shape(params: bytes) -> tuple[int, int] | None:
    """(start address, bytes per servo block: ID + data) of SYNC_WRITE parameters, or
    None when they cannot be split into whole blocks."""
    if len(params) < 2:
        return None
    address, length = params[0], params[1]
    if length == 0 or (len(params) - 2) % (length + 1):
        return None
    return address, length + 1


class ServoPackets:
    """What the servo does with the packets it hears (a part of
    :class:`~snakebot.sim.servo.reference.ReferenceServo`, working on the attributes it
    sets up)."""

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

    def _plan(self, address: int, length: int) -> WritePlan:
        """The plan of a write of ``length`` bytes at ``address`` in the present Lock
        state, cached under ``address << 9 | length << 1 | locked``."""
        locked = self._lock == 1
        key = address << 9 | length << 1 | locked
        plan = self._plans.get(key)
        if plan is None:
            entries = self.regs.layout(address, length, locked)
            plan = _BAD_WRITE if entries is None else WritePlan(self.regs, address, entries)
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
                self._speed_setting = SPEED_SETTINGS[speed & motor.SPEED_MAX]
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

    def _commit(self, plan: WritePlan, data: bytes, values: list[int]) -> None:
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
            self._speed_setting = SPEED_SETTINGS[self._moving_speed & motor.SPEED_MAX]
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
