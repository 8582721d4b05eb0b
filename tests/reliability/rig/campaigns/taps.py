"""What the firmware puts on the bus, and what comes back: the taps on the emulated bus and
servos that the checks count from."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from snakebot.formats import protocol
from snakebot.formats.protocol import (
    Instruction,
    Packet,
    PacketParser,
)
from snakebot.sim.bus.bus import Bus
from snakebot.sim.servo.fast import VirtualServo
from tests.reliability.rig.campaigns.testbed import (
    AX12,
    GOAL_BLOCK,
    GOAL_POSITION,
    TELEMETRY_ADDRESS,
    TELEMETRY_PARAMS,
    TORQUE_ENABLE,
)


@dataclass
class Tap:
    """Counts the firmware's bus traffic: its own bytes (before any damage) and the bytes
    that reach it, transaction by transaction."""

    limits: dict[int, tuple[int, int]]
    goal_packets: int = 0
    goals: int = 0
    goals_outside: int = 0
    torque_on: int = 0
    torque_off: int = 0
    packets: int = 0  # every packet the firmware put on the bus
    reads_sent: int = 0
    reads_answered: int = 0  # an intact reply of the right shape reached the firmware
    reads_damaged: int = 0  # a damaged reply from the addressed servo reached it
    unanswered: Counter = field(default_factory=Counter)  # per servo ID
    max_gap_s: float = 0.0
    _sent: PacketParser = field(default_factory=PacketParser)
    _pending: int | None = None  # ID of the READ in flight
    _rx: bytearray = field(default_factory=bytearray)  # what reached the firmware since
    _prelude: bytearray = field(default_factory=bytearray)  # heard since the last packet
    _last_t: float | None = None
    outside_examples: list[tuple[int, int]] = field(default_factory=list)

    def _close_read(self) -> None:
        """Judge the READ in flight by the bytes that may have reached the firmware in its
        reply window: an intact status packet of its servo with the telemetry block
        anywhere in them is an answer; otherwise a damaged one (right header, ID and
        length, wrong checksum) makes it a damaged reply, and nothing at all a lost one.
        The window is taken as wide as it can be, so these are upper bounds on the reads
        and damaged replies the firmware can count."""
        sid = self._pending
        if sid is None:
            return
        rx, n = bytes(self._rx), TELEMETRY_PARAMS + 6
        answered = damaged = False
        for i in range(len(rx) - n + 1):
            w = rx[i : i + n]
            if w[:4] != bytes([0xFF, 0xFF, sid, TELEMETRY_PARAMS + 2]):
                continue
            if protocol.checksum(w[2:-1]) == w[-1]:
                answered = True
                break
            damaged = True
        if answered:
            self.reads_answered += 1
        else:
            self.unanswered[sid] += 1
            self.reads_damaged += damaged
        self._pending = None
        self._rx.clear()

    def sent(self, t: float, data: bytes) -> None:
        if self._last_t is not None:
            self.max_gap_s = max(self.max_gap_s, t - self._last_t)
        self._last_t = t
        for event in self._sent.feed(data):
            if not isinstance(event, Packet):
                continue
            self.packets += 1
            self._close_read()
            prelude = bytes(self._prelude)
            self._prelude.clear()
            p = event.params
            if event.code == Instruction.SYNC_WRITE and p[:2] == bytes([GOAL_POSITION, GOAL_BLOCK]):
                self.goal_packets += 1
                for k in range(2, len(p) - GOAL_BLOCK, GOAL_BLOCK + 1):
                    sid, goal = p[k], p[k + 1] | p[k + 2] << 8
                    lo, hi = self.limits.get(sid, AX12.require_position().range)
                    self.goals += 1
                    if not lo <= goal <= hi:
                        self.goals_outside += 1
                        self.outside_examples.append((sid, goal))
            elif event.code == Instruction.SYNC_WRITE and p[:1] == bytes([TORQUE_ENABLE]):
                self.torque_on += 1
            elif event.code == Instruction.WRITE and p[:2] == bytes([TORQUE_ENABLE, 0]):
                self.torque_off += 1
            elif event.code == Instruction.READ and p[:1] == bytes([TELEMETRY_ADDRESS]):
                self.reads_sent += 1
                # The firmware empties its receiver just before it sends, so what reached
                # the bus side since the previous packet may still count for this READ.
                self._pending = event.id
                self._rx[:] = prelude

    def heard(self, data: bytes) -> None:
        (self._rx if self._pending is not None else self._prelude).extend(data)

    def quiet(self) -> None:
        """The bus is idle now: the READ in flight, if any, is over; gaps restart."""
        self._close_read()
        self._last_t = None

    def restart_gaps(self) -> None:
        """Measure the longest silence between packets from now on."""
        self._last_t = None


class TappedBus(Bus):
    """The emulated bus, with the firmware's side of the wire counted by a :class:`Tap`."""

    def __init__(self, tap: Tap, *args: Any, **kwargs: Any) -> None:
        self.tap = tap
        super().__init__(*args, **kwargs)

    def master_write(self, data: bytes) -> None:
        self.tap.sent(self.now, bytes(data))  # before the wire can damage it
        super().master_write(data)

    def master_read(self, size: int) -> bytes:
        out = super().master_read(size)
        if out:
            self.tap.heard(out)
        return out


class AuditedServo(VirtualServo):
    """A virtual AX-12 that keeps account of what it accepted: WRITEs that reached its
    angle limits (EEPROM), and every goal it took outside the robot's limits for it
    (whatever the wire did to the packet that carried it)."""

    def __init__(self, servo_id: int, robot_limits: tuple[int, int]) -> None:
        super().__init__(servo_id)
        self.robot_limits = robot_limits
        cw, ccw = self.regs.entry("CW Angle Limit"), self.regs.entry("CCW Angle Limit")
        self._angle_span = (cw.address, ccw.address + ccw.size)
        self.angle_limit_writes = 0
        self.goals_outside: list[int] = []

    def _write_at(self, address: int, data: bytes, registered: bool) -> int:
        goal = self._goal
        flags = super()._write_at(address, data, registered)
        if flags == 0 and not registered:
            lo, hi = self._angle_span
            self.angle_limit_writes += address < hi and address + len(data) > lo
            low, high = self.robot_limits
            if self._goal != goal and not low <= self._goal <= high:
                self.goals_outside.append(self._goal)
        return flags

    def angle_limits(self) -> tuple[int, int]:
        return self.regs.get("CW Angle Limit"), self.regs.get("CCW Angle Limit")
