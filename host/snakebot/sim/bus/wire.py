"""Bytes on the wire: transmissions at their sender's rate, what a receiver at another
rate hears of them, collisions (every byte slot two drivers share is garbled), the
master hearing servos, noise and, with ``echo``, itself, the servos' status packets
after Return Delay Time, and noise bursts."""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

from snakebot.formats.protocol import Instruction
from snakebot.sim.bus.clock import BITS_PER_BYTE
from snakebot.sim.bus.listeners import Group
from snakebot.sim.bus.state import BusState
from snakebot.sim.bus.uart import resample, same_baud
from snakebot.sim.servo.fast import VirtualServo

MASTER = "master"
NOISE = "noise"

_EPS = 1e-12
SYNC_WRITE_CODE = int(Instruction.SYNC_WRITE)
READ_CODE = int(Instruction.READ)


class Heard:
    """What one receiver hears of one transmission: byte i is complete at
    ``start + (i + 1) * period`` (same rate: shares the transmission's bytes, so later
    damage from a collision is heard too) or at ``times[i]`` (resampled)."""

    __slots__ = ("data", "start", "period", "times", "pos")

    def __init__(
        self,
        data: bytearray | bytes,
        start: float,
        period: float,
        times: list[float] | None = None,
    ) -> None:
        self.data = data
        self.start = start
        self.period = period
        self.times = times
        self.pos = 0

    @classmethod
    def of(cls, tx: Transmission, rx_baud: float) -> Heard:
        if tx.baud == rx_baud or same_baud(tx.baud, rx_baud):
            return cls(tx.data, tx.start, tx.period)
        pairs = resample(bytes(tx.data), tx.baud, rx_baud)
        return cls(
            bytes(b for _, b in pairs), tx.start, tx.period, [tx.start + t for t, _ in pairs]
        )

    def arrival(self, i: int) -> float:
        if self.times is None:
            return self.start + (i + 1) * self.period
        return self.times[i]

    def count_by(self, t: float) -> int:
        """How many bytes are complete at time ``t``."""
        n = len(self.data)
        if self.times is None:
            k = math.floor((t - self.start) / self.period + 1e-6)
            return 0 if k < 0 else (k if k < n else n)
        k = self.pos
        while k < n and self.times[k] <= t + _EPS:
            k += 1
        return k


class Transmission(Heard):
    """Bytes one driver puts on the wire, back to back from ``start``; also what a
    receiver at the same rate hears of them (byte i complete at :meth:`arrival`), the
    master included (``pos``: how many of them it has read)."""

    __slots__ = ("source", "baud", "end", "unheard")

    def __init__(self, source: object, start: float, baud: float, data: bytearray | bytes) -> None:
        self.source = source
        self.unheard: Group | None = None
        """The group whose delivery was skipped as nobody there would act on it (see
        ``Bus._transmit``); delivered after all if a collision damages the bytes."""
        self.start = start
        self.baud = baud
        self.period = period = BITS_PER_BYTE / baud  # clock.byte_time
        self.data = data
        self.end = start + len(data) * period
        self.times = None
        self.pos = 0


@dataclass
class BusStats:
    """Counters of what happened on the wire."""

    master_bytes_out: int = 0
    master_bytes_in: int = 0
    instructions: int = 0
    replies: int = 0
    collisions: int = 0


class Wire(BusState):
    """The line itself (a part of :class:`~snakebot.sim.bus.bus.Bus`)."""

    def _put_on_wire(self, tx: Transmission) -> None:
        """The master's frame ``tx`` onto a line that is quiet by the time it starts:
        what is still on the wire stays there, untouched."""
        now = self.now
        if self._wire_end > now:
            self._wire = [other for other in self._wire if other.end > now]
            self._wire.append(tx)
        else:
            self._wire = [tx]
        self._wire_end = tx.end

    def _transmit(self, source: object, start: float, baud: float, data: bytearray) -> Transmission:
        if self._held is not None:
            self._release()  # on the wire: what this transmission may collide with
        if self._corrupting:
            self.faults.corrupt(data)
        tx = Transmission(source, start, baud, data)
        now = self.now
        if self._wire_end > now:  # something may still be on the wire
            wire = [other for other in self._wire if other.end > now]
            for other in wire:
                if other.end > tx.start and other.start < tx.end:
                    self._collide(other, tx)
            wire.append(tx)
            self._wire = wire
            if tx.end > self._wire_end:
                self._wire_end = tx.end
        else:  # the line is quiet (the usual case): nothing to collide with
            self._wire = [tx]
            self._wire_end = tx.end
        # the master hears servos and noise, and its own bytes when the line echoes
        if source is not MASTER or self.echo:
            if baud == self.baudrate:
                self._master_rx.append(tx)  # heard as sent
            else:
                self._master_rx.append(Heard.of(tx, self.baudrate))
        # the servos hear everything but their own voice
        groups = self._groups
        if groups is None:
            groups = self._listeners()
        n = len(data)
        whole = n >= 6 and data[0] == 0xFF and data[1] == 0xFF and data[2] != 0xFF
        if whole and data[3] + 4 == n:
            # one whole frame, the usual case: a group at the sender's rate hears it
            # whole when its last byte is in (tx.end)
            for group in groups:
                rx = group.rx
                members = group.members
                if len(members) == 1 and members[0] is source:
                    continue
                if baud != rx.baud:
                    self._schedule(group, tx, source)
                    continue
                if source is MASTER:
                    if n == 8 and data[4] == READ_CODE and group.c_by_id is not None:
                        job = (group, tx)  # the commonest packet: see _deliver_read
                        deliver = self._deliver_read
                    else:
                        job, deliver = (group, tx, 0, n, source), self._deliver
                elif source is not NOISE and self._unheard(group, tx):
                    continue
                else:
                    job, deliver = (group, tx, 0, n, source), self._deliver
                heapq.heappush(self._events, (tx.end, next(self._seq), deliver, job))
                rx.queued += 1
        else:
            for group in groups:
                if not (len(group.members) == 1 and group.members[0] is source):
                    self._schedule(group, tx, source)
        if source is MASTER:
            self.stats.instructions += 1
        return tx

    def _collide(self, a: Transmission, b: Transmission) -> None:
        lo = max(a.start, b.start)
        hi = min(a.end, b.end)
        self.stats.collisions += 1
        for tx in (a, b):
            group = tx.unheard
            if group is not None:  # damaged now: the group hears it after all
                tx.unheard = None
                job = (group, tx, 0, len(tx.data), tx.source)
                heapq.heappush(self._events, (tx.end, next(self._seq), self._deliver, job))
                group.rx.queued += 1
            i0 = max(0, math.floor((lo - tx.start) / tx.period))
            i1 = min(len(tx.data), math.ceil((hi - tx.start) / tx.period))
            data = tx.data
            if type(data) is bytes:
                # a fast path's frame, heard by nobody but through ``tx`` itself
                tx.data = data = bytearray(data)
            for i in range(i0, i1):
                data[i] = self.faults.collision_byte()

    def _reply(self, servo: VirtualServo, reply: tuple[bytes, float], t: float) -> None:
        packet, baud = reply
        start = t + servo.return_delay_s
        if self._reply_faults:
            faults = self.faults
            if faults.drop_reply():
                return
            start += faults.reply_delay()
        key = id(servo)
        free = self._servo_tx_free.get(key, 0.0)
        if free > start:
            start = free
        tx = self._transmit(servo, start, baud, bytearray(packet))
        self._servo_tx_free[key] = tx.end
        self.stats.replies += 1

    def _noise_burst(self, t: float, data: bytes) -> None:
        self._transmit(NOISE, t, self.baudrate, bytearray(data))
        nxt = self.faults.next_noise(t)
        if nxt is not None:
            self.at(nxt[0], self._noise_burst, nxt[1])
