"""The emulated Dynamixel line: one master, several virtual servos, one wire.

Everything happens on the bus's virtual clock (:attr:`Bus.now`, seconds), which moves
only when :meth:`Bus.run_until` (or a transport on the bus's behalf) moves it:

* A transmission occupies the wire for 10 bits a byte at its sender's baud rate. Each
  receiver hears it at its own rate: the same bytes when the rates agree, and what a
  UART sampling at the wrong rate makes of it otherwise (``snakebot.sim.bus.uart``), which is
  how a servo left on another baud rate hears garbage.
* Servos that share a baud rate hear the same bytes, so they share one receiver
  (``snakebot.sim.bus.receiver``: byte by byte, a damaged frame dropped whole); a packet is
  handed to every servo when its last byte has arrived, and the status packet goes out
  Return Delay Time later. A gap of more than 100 ms inside a packet makes the servos
  drop it.
* Two drivers on the wire at once (two servos with one ID, a servo answering while the
  master still talks, a noise burst) garble every byte slot they share.
* With ``echo`` on, the master hears its own instruction, as on a one-wire adapter.
* Faults (``snakebot.sim.bus.faults``) are injected from a seed, reproducibly.

A world (body kinematics) steps on the same clock: register a callback with
:meth:`Bus.every` and read the servos' present positions in it (:meth:`Bus.positions`).
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from snakebot.core import ffi, lib
from snakebot.formats.protocol import (
    BROADCAST_ID,
    FRAME_RESET_S,
    MAX_PACKET_LEN,
    Instruction,
    Packet,
)
from snakebot.sim.bus.clock import BITS_PER_BYTE
from snakebot.sim.bus.faults import FaultConfig, FaultInjector
from snakebot.sim.bus.receiver import ServoReceiver
from snakebot.sim.bus.uart import resample, same_baud
from snakebot.sim.servo.fast import VirtualServo
from snakebot.sim.servo.reference import sync_write_shape

INTER_BYTE_GAP_S = FRAME_RESET_S
"""A pause longer than this inside a packet makes a servo drop the partial packet."""

MASTER = "master"
NOISE = "noise"

_EPS = 1e-12
_SYNC_WRITE = int(Instruction.SYNC_WRITE)
_READ = int(Instruction.READ)


class _Heard:
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
    def of(cls, tx: _Transmission, rx_baud: float) -> _Heard:
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


class _Transmission(_Heard):
    """Bytes one driver puts on the wire, back to back from ``start``; also what a
    receiver at the same rate hears of them (byte i complete at :meth:`arrival`), the
    master included (``pos``: how many of them it has read)."""

    __slots__ = ("source", "baud", "end", "unheard")

    def __init__(self, source: object, start: float, baud: float, data: bytearray | bytes) -> None:
        self.source = source
        self.unheard: _Group | None = None
        """The group whose delivery was skipped as nobody there would act on it (see
        ``Bus._transmit``); delivered after all if a collision damages the bytes."""
        self.start = start
        self.baud = baud
        self.period = period = BITS_PER_BYTE / baud  # clock.byte_time
        self.data = data
        self.end = start + len(data) * period
        self.times = None
        self.pos = 0


class _Receiver:
    """The servos that share one baud rate, and the receive state they share (they hear
    the same bytes, so they find the same packets)."""

    __slots__ = ("baud", "parser", "last_t", "queued")

    def __init__(self, baud: float) -> None:
        self.baud = baud
        self.parser = ServoReceiver()
        self.last_t = -math.inf
        self.queued = 0  # deliveries scheduled and not yet made


class _Group:
    """The powered servos at one baud rate: their shared receiver, the servos in bus
    order, and an index of them by ID (several when IDs collide), so a packet for one
    ID costs the same however many servos share the line.

    Packets already on their way keep the group they were sent to, as its servos were
    listening then; but a servo answers to the ID it has when a packet lands, so the
    index is rebuilt when IDs have changed since (``epoch``: the bus's count of link
    changes it was built at)."""

    __slots__ = ("rx", "members", "by_id", "c_by_id", "epoch", "c_path")

    def __init__(
        self, rx: _Receiver, members: list[VirtualServo], epoch: int, c_path: bool = True
    ) -> None:
        self.rx = rx
        self.members = members
        self.c_path = c_path
        self.reindex(epoch)

    def reindex(self, epoch: int) -> None:
        self.by_id: dict[int, list[VirtualServo]] = {}
        for s in self.members:
            self.by_id.setdefault(s.id, []).append(s)
        self.epoch = epoch
        # The same index for the C servos (a SYNC_WRITE handled in one call), when every
        # servo here is one and no two share an ID; None otherwise.
        self.c_by_id = None
        structs = [getattr(s, "c_struct", None) for s in self.members]
        if self.c_path and None not in structs and len(self.by_id) == len(self.members):
            self.c_by_id = ffi.new("sim_servo *[256]")
            for s, struct in zip(self.members, structs, strict=True):
                self.c_by_id[s.id] = struct


class Schedule:
    """A call repeated on the bus clock (:meth:`Bus.every`): the ``n``-th at
    ``first + n * period``, until :meth:`cancel`."""

    __slots__ = ("bus", "period", "fn", "first", "count", "cancelled")

    def __init__(
        self, bus: Bus, period: float, fn: Callable[[float], object], first: float
    ) -> None:
        self.bus = bus
        self.period = period
        self.fn = fn
        self.first = first
        self.count = 0
        self.cancelled = False

    def tick(self, t: float) -> None:
        if self.cancelled:
            return
        self.fn(t)
        self.count += 1
        if not self.cancelled:
            self.bus.at(self.first + self.count * self.period, self.tick)

    def cancel(self) -> None:
        """No more calls (also when called from the schedule's own call)."""
        if not self.cancelled:
            self.cancelled = True
            self.bus._unschedule(self.tick)


@dataclass
class BusStats:
    """Counters of what happened on the wire."""

    master_bytes_out: int = 0
    master_bytes_in: int = 0
    instructions: int = 0
    replies: int = 0
    collisions: int = 0


def frame_ends(data: bytes | bytearray) -> list[int]:
    """Where the packets in ``data`` end, by header and LEN alone: the points at which a
    receiver's parser is fed, so each packet is handled when its last byte arrives."""
    ends = []
    i, n = 0, len(data)
    while i < n:
        j = data.find(b"\xff\xff", i)
        if j < 0:
            break
        while j + 2 < n and data[j + 2] == 0xFF:
            j += 1
        if j + 3 >= n:
            break
        end = j + 4 + data[j + 3]
        if end >= n:
            break
        ends.append(end)
        i = end
    ends.append(n)
    return ends


class Bus:
    """A Dynamixel line with virtual servos on a virtual clock; the host is the master.

    ``baudrate`` is the master's UART rate (the servos each have their own, from their
    Baud Rate register). ``echo``: the master hears its own instructions.
    """

    def __init__(
        self,
        servos: Iterable[VirtualServo] = (),
        *,
        baudrate: float = 1_000_000,
        echo: bool = False,
        faults: FaultConfig | None = None,
        supply_v: float | None = None,
    ) -> None:
        self.now = 0.0
        self.servos: list[VirtualServo] = list(servos)
        self.baudrate = baudrate
        self.echo = echo
        self.fault_config = faults or FaultConfig()
        self.faults = FaultInjector(self.fault_config)
        self._corrupting = self.fault_config.corrupt > 0
        config = self.fault_config
        self._reply_faults = bool(config.drop or config.delay_s or config.jitter_s)
        self.stats = BusStats()
        self._events: list[tuple[float, int, Callable, object]] = []
        self._seq = itertools.count()
        self._wire: list[_Transmission] = []
        self._wire_end = -math.inf  # when the last of them ends
        self._c_reply = ffi.new("uint8_t[]", 256)  # a C servo's status packet
        self._c_reply_bytes = ffi.buffer(self._c_reply)  # sliced: a copy as bytes
        # one bound method, so that master_receive knows a READ's delivery by identity
        self._deliver_read_cb = self._deliver_read
        # a READ written and not yet on the wire or due (see master_write, _release):
        # (start, end, event sequence number, group, frame)
        self._held: tuple[float, float, int, _Group, bytes] | None = None
        self._master_rx: list[_Heard] = []
        self._master_tx_free = 0.0
        self._servo_tx_free: dict[int, float] = {}
        self._receivers: dict[float, _Receiver] = {}
        self._groups: list[_Group] | None = None
        self._quiet_reply: _Group | None = None  # the group of _listeners, when alone
        self._c_path = True  # whole packets to the C servos (tap() turns it off)
        self._link_epoch = 0  # link changes so far (_Group.epoch)
        self._by_id: dict[int, VirtualServo] | None = None  # the first servo with each ID
        self._indexed = 0  # how many servos the index was built from
        for s in self.servos:
            s.on_link_change = self._link_changed
        if supply_v is not None:
            self.set_supply(supply_v)
        for b in self.fault_config.brownouts:
            victims = [s for s in self.servos if s.id == b.servo_id]
            for s in victims:
                self.at(b.start_s, lambda t, s=s: s.power_off(t))
                self.at(b.start_s + b.duration_s, lambda t, s=s: s.power_on(t))
        noise = self.faults.next_noise(0.0)
        if noise is not None:
            self.at(noise[0], self._noise_burst, noise[1])

    # -- set-up ---------------------------------------------------------------------------

    def add(self, servo: VirtualServo) -> VirtualServo:
        """Put another servo on the line."""
        servo.advance(self.now)
        servo.t = self.now
        servo.on_link_change = self._link_changed
        self.servos.append(servo)
        self._groups = None
        self._by_id = None
        return servo

    def tap(self) -> None:
        """From now on every packet goes through the servos' Python handlers
        (``receive``, ``sync_write_block``), slower than handing whole packets to the C
        servos, so that a test or a tool that wraps those handlers hears every one."""
        self._c_path = False
        self._groups = None

    def _link_changed(self, _servo: VirtualServo) -> None:
        # a servo changed baud rate or ID, or lost/regained power
        self._groups = None
        self._by_id = None
        self._link_epoch += 1

    def _listeners(self) -> list[_Group]:
        """The powered servos grouped by baud rate, each group with its shared parser."""
        if self._groups is None:
            by_baud: dict[float, list[VirtualServo]] = {}
            for s in self.servos:
                if s.powered:
                    by_baud.setdefault(s.baudrate, []).append(s)
            groups = []
            for baud, members in by_baud.items():
                rx = self._receivers.get(baud)
                if rx is None:
                    rx = self._receivers[baud] = _Receiver(baud)
                groups.append(_Group(rx, members, self._link_epoch, self._c_path))
            self._groups = groups
            # see _deliver_read
            plain = len(groups) == 1 and not (self._corrupting or self._reply_faults)
            self._quiet_reply = groups[0] if plain else None
        return self._groups

    def servo(self, servo_id: int) -> VirtualServo:
        """The (first) servo answering to ``servo_id``."""
        by_id = self._by_id
        if by_id is None or self._indexed != len(self.servos):
            by_id = {}
            for s in self.servos:
                by_id.setdefault(s.id, s)
            self._by_id = by_id
            self._indexed = len(self.servos)
        try:
            return by_id[servo_id]
        except KeyError:
            raise KeyError(f"no servo with ID {servo_id} on the bus") from None

    def set_supply(self, volts: float) -> None:
        """Set the supply voltage every servo sees (from now on)."""
        for s in self.servos:
            s.set_supply(self.now, volts)

    # -- the clock ------------------------------------------------------------------------

    def at(self, t: float, fn: Callable, arg: object = None) -> None:
        """Call ``fn(t)`` (or ``fn(t, arg)`` when ``arg`` is given) at bus time ``t``."""
        heapq.heappush(self._events, (t, next(self._seq), fn, arg))

    def every(
        self, period: float, fn: Callable[[float], object], start: float | None = None
    ) -> Schedule:
        """Call ``fn(t)`` at ``start`` (default: now) and every ``period`` seconds after,
        in time order with the bus's own events: how a world steps with the servos.
        Returns the schedule, to :meth:`Schedule.cancel` it."""
        if not period > 0:
            raise ValueError("period must be positive")
        schedule = Schedule(self, period, fn, self.now if start is None else start)
        self.at(schedule.first, schedule.tick)
        return schedule

    def _unschedule(self, fn: Callable) -> None:
        """Drop the pending events that would call ``fn``."""
        kept = [e for e in self._events if e[2] != fn]
        if len(kept) != len(self._events):
            heapq.heapify(kept)
            self._events[:] = kept

    def next_event_time(self) -> float | None:
        """When the next scheduled event happens (None if none)."""
        if self._held is not None:
            self._release()
        return self._events[0][0] if self._events else None

    def run_until(self, t: float) -> None:
        """Run every event up to bus time ``t`` and leave the clock at ``t``."""
        held = self._held
        if held is not None and held[1] <= t:
            self._release()
        events = self._events
        while events and events[0][0] <= t:
            et, _, fn, arg = heapq.heappop(events)
            if et > self.now:
                self.now = et
            if arg is None:
                fn(self.now)
            else:
                fn(self.now, arg)
        if t > self.now:
            self.now = t

    def advance(self, dt: float) -> None:
        """Run the bus for ``dt`` seconds."""
        self.run_until(self.now + dt)

    def run_until_master_data(self, deadline: float, count: int = 1) -> bool:
        """Run until ``count`` bytes for the master have arrived or ``deadline`` passes;
        return whether any have. What a blocking read does in virtual time."""
        if self._held is not None:
            self._release()
        events = self._events
        while True:
            streams = self._master_rx
            if len(streams) == 1:
                # one stream on its way (a status packet), worked out in place: what
                # master_in_waiting and next_master_arrival say of it
                h = streams[0]
                n = len(h.data)
                if h.times is None:  # count_by and arrival at one rate, inline
                    k = math.floor((self.now - h.start) / h.period + 1e-6)
                    k = 0 if k < 0 else (k if k < n else n)
                else:
                    k = h.count_by(self.now)
                available = k - h.pos
                if available >= count:
                    return True
                if k >= n:
                    t_byte = None
                else:
                    i = k + count - available - 1
                    if i >= n:
                        i = n - 1
                    t_byte = h.start + (i + 1) * h.period if h.times is None else h.times[i]
            elif streams:
                available = self.master_in_waiting()
                if available >= count:
                    return True
                t_byte = self.next_master_arrival(count - available)
            else:
                t_byte = None  # nothing on its way to the master yet
            t_event = events[0][0] if events else math.inf
            if t_byte is not None and t_byte <= self.now:
                break  # cannot happen (arrived bytes are counted); never spin on it
            if t_byte is not None and t_byte <= t_event:
                if t_byte > deadline:
                    break
                if t_byte < t_event:
                    self.now = t_byte  # no event on the way: run_until(t_byte) in short
                else:
                    self.run_until(t_byte)
                continue
            if t_event > deadline:
                break
            self.run_until(t_event)
        if deadline != math.inf:
            self.run_until(deadline)
        return self.master_in_waiting() > 0

    # -- the world's view ------------------------------------------------------------------

    def positions(self, ids: Iterable[int] | None = None) -> list[float]:
        """Present positions (ticks, unrounded) now, for ``ids`` in order or every servo."""
        servos = self.servos if ids is None else [self.servo(i) for i in ids]
        now = self.now
        for s in servos:
            s.advance(now)
        return [s.pos for s in servos]

    # -- the master's side ----------------------------------------------------------------

    def master_write(self, data: bytes) -> None:
        """The master sends ``data`` (starting now, or when its UART is free)."""
        if not data:
            return
        if self._held is not None:
            self._release()
        now = self.now
        start = now if now > self._master_tx_free else self._master_tx_free
        group = self._quiet_reply
        n = len(data)
        if (
            n >= 6
            and group is not None
            and self._wire_end <= start
            and not self.echo
            and group.c_by_id is not None
            and self._groups is not None
            and group.rx.baud == self.baudrate
            and data[0] == data[1] == 0xFF != data[2]
            and data[3] + 4 == n
        ):
            # one whole frame to the one group of C servos (see _deliver_read) on a line
            # that is quiet by the time it starts (after the master's own frame before
            # it, a SYNC_WRITE say): what _transmit does with it, in short; a READ and a
            # SYNC_WRITE then go to the C servos whole, anything else to _deliver
            # bytes, shared: _collide makes a bytearray of them if they get damaged
            frame = data if type(data) is bytes else bytes(data)
            code = frame[4]
            if code == _READ and n == 8:
                # held (see _release): its transmission and delivery event are made
                # only if something other than master_receive comes first
                end = start + n * (BITS_PER_BYTE / group.rx.baud)  # as _Transmission
                self._held = (start, end, next(self._seq), group, frame)
                self._wire_end = end
            else:
                tx = _Transmission(MASTER, start, group.rx.baud, frame)
                self._put_on_wire(tx)
                end = tx.end
                if code == _SYNC_WRITE:
                    job: tuple = (group, tx)
                    deliver = self._deliver_sync_write
                else:
                    job, deliver = (group, tx, 0, n, MASTER), self._deliver
                heapq.heappush(self._events, (end, next(self._seq), deliver, job))
            group.rx.queued += 1
            self.stats.instructions += 1
        else:
            end = self._transmit(MASTER, start, self.baudrate, bytearray(data)).end
        self._master_tx_free = end
        self.stats.master_bytes_out += n

    def _put_on_wire(self, tx: _Transmission) -> None:
        """The master's frame ``tx`` onto a line that is quiet by the time it starts:
        what is still on the wire stays there, untouched."""
        now = self.now
        if self._wire_end > now:
            self._wire = [other for other in self._wire if other.end > now]
            self._wire.append(tx)
        else:
            self._wire = [tx]
        self._wire_end = tx.end

    def _release(self) -> None:
        """The held READ (``master_write``) as the bus would have it had it not been
        held: on the wire, its delivery due at its end (in its place in the order)."""
        start, end, seq, group, frame = self._held
        self._held = None
        tx = _Transmission(MASTER, start, group.rx.baud, frame)
        self._put_on_wire(tx)
        heapq.heappush(self._events, (end, seq, self._deliver_read_cb, (group, tx)))

    @property
    def master_tx_done(self) -> float:
        """When the master's UART will have sent everything it was given."""
        return self._master_tx_free

    def master_in_waiting(self) -> int:
        """Bytes that have reached the master and not been read."""
        streams = self._master_rx
        if not streams:
            return 0
        now = self.now
        if len(streams) == 1:
            h = streams[0]
            return h.count_by(now) - h.pos
        return sum(h.count_by(now) - h.pos for h in streams)

    def next_master_arrival(self, count: int = 1) -> float | None:
        """When ``count`` more bytes still on their way will have reached the master (the
        last of them, if fewer are on their way); None if none are on their way."""
        streams = self._master_rx
        if not streams:
            return None
        now = self.now
        if len(streams) == 1:
            h = streams[0]
            last = len(h.data) - 1
            k = h.count_by(now)
            if k > last:
                return None
            i = k + count - 1
            return h.arrival(i if i < last else last)
        times = []
        for h in streams:
            k = h.count_by(now)
            times += [h.arrival(i) for i in range(k, min(len(h.data), k + count))]
        if not times:
            return None
        times.sort()
        return times[min(count, len(times)) - 1]

    def master_read(self, size: int) -> bytes:
        """Up to ``size`` bytes that have reached the master, oldest first."""
        streams = self._master_rx
        if not streams or size <= 0:
            return b""
        now = self.now
        if len(streams) == 1:
            h = streams[0]
            k = min(h.count_by(now), h.pos + size)
            out = bytes(h.data[h.pos : k])
            h.pos = k
            if k >= len(h.data):
                streams.clear()
        else:
            # several streams (a collision, noise, echo): merge what has arrived by time
            arrived = sorted(
                (h.arrival(i), n, i)
                for n, h in enumerate(streams)
                for i in range(h.pos, h.count_by(now))
            )[:size]
            out = bytes(streams[n].data[i] for _, n, i in arrived)
            for _, n, i in arrived:
                streams[n].pos = i + 1
            self._master_rx = [h for h in streams if h.pos < len(h.data)]
        self.stats.master_bytes_in += len(out)
        return out

    def master_receive(self, size: int, deadline: float) -> bytes:
        """What a timed read gets: :meth:`run_until_master_data` for ``size`` bytes by
        ``deadline``, then :meth:`master_read` of ``size``, in one call.

        The closed loop's transaction takes a short way through it: when the next thing
        due is the C servos' answer to a READ (``_deliver_read``) and the master has
        nothing else on its way, the status packet is made and the clock goes straight
        to the arrival of the byte that completes the read, if nothing else is due
        before then; the same steps as the general loop's, without its rounds."""
        events = self._events
        while not self._master_rx:
            held = self._held
            if held is not None:
                due = held[1]
                if due <= deadline and (
                    not events
                    or events[0][0] > due
                    or (events[0][0] == due and events[0][1] > held[2])
                ):
                    out = self._answer_held(size, deadline)
                    if out is not None:
                        return out
                    break  # taken some way: the general loop goes on from there
                if not events or events[0][0] > deadline:
                    break
            elif not events or events[0][0] > deadline:
                break
            et, _, fn, job = events[0]
            if fn is not self._deliver_read_cb:
                # nothing on its way yet: the general loop's step (the goals' SYNC_WRITE
                # before the READ, say)
                self.run_until(et)
                continue
            heapq.heappop(events)
            if et > self.now:
                self.now = et
            self._deliver_read(self.now, job)
            out = self._take_whole(size, deadline)
            if out is not None:
                return out
            break
        if self.run_until_master_data(deadline, size):
            return self.master_read(size)
        return b""

    def _answer_held(self, size: int, deadline: float) -> bytes | None:
        """The held READ delivered now, due next: what ``_deliver_read`` and then
        ``_take_whole`` do, and when the whole status packet is read at once and
        nothing is due before its end, without making either transmission (the READ's
        has ended; the status packet's is heard whole, and by nobody else). None if
        the read is not done (the general loop goes on from the state left)."""
        start, end, _, group, frame = self._held
        self._held = None
        if end > self.now:
            self.now = end
        t = self.now
        n = self._c_read(group, frame, t)
        if not n:
            self._deliver(
                t, (group, _Transmission(MASTER, start, group.rx.baud, frame), 0, 8, MASTER)
            )
            return None
        servo = self._read_answered(group, frame, n, t)
        if servo is None:
            return None
        reply_end = t + servo.return_delay_s + n * (BITS_PER_BYTE / group.rx.baud)
        events = self._events
        if size != n or reply_end > deadline or (events and events[0][0] <= reply_end):
            self._quiet_reply_out(group, servo, n, t)
            return self._take_whole(size, deadline)
        self._wire_end = self._servo_tx_free[id(servo)] = self.now = reply_end
        stats = self.stats
        stats.replies += 1
        stats.master_bytes_in += n
        return self._c_reply_bytes[:n]

    def _take_whole(self, size: int, deadline: float) -> bytes | None:
        """The first ``size`` bytes of the one stream on its way to the master, nothing
        read of it yet, with the clock moved to the last one's arrival, as
        ``run_until_master_data`` and ``master_read`` would: when they arrive by
        ``deadline`` with no event due before; None otherwise (nothing done)."""
        streams = self._master_rx
        if len(streams) != 1:
            return None
        h = streams[0]
        data = h.data
        n = len(data)
        if h.times is not None or h.pos or not 0 < size <= n:
            return None
        t_byte = h.start + size * h.period  # arrival(size - 1)
        events = self._events
        if not self.now < t_byte <= deadline or (events and events[0][0] <= t_byte):
            return None
        if h.count_by(t_byte) < size:
            return None  # rounding: leave it to the general loop
        self.now = t_byte
        if size == n:
            streams.clear()
            out = data if type(data) is bytes else bytes(data)
        else:
            h.pos = size
            out = bytes(data[:size])
        self.stats.master_bytes_in += size
        return out

    def master_flush_input(self) -> None:
        """Discard what has reached the master (bytes still on the wire will arrive)."""
        if not self._master_rx:
            return
        now = self.now
        for h in self._master_rx:
            h.pos = max(h.pos, h.count_by(now))
        self._master_rx = [h for h in self._master_rx if h.pos < len(h.data)]

    # -- the wire -------------------------------------------------------------------------

    def _transmit(
        self, source: object, start: float, baud: float, data: bytearray
    ) -> _Transmission:
        if self._held is not None:
            self._release()  # on the wire: what this transmission may collide with
        if self._corrupting:
            self.faults.corrupt(data)
        tx = _Transmission(source, start, baud, data)
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
                self._master_rx.append(_Heard.of(tx, self.baudrate))
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
                    if n == 8 and data[4] == _READ and group.c_by_id is not None:
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

    def _schedule(self, group: _Group, tx: _Transmission, source: object) -> None:
        """Schedule what ``group`` hears of ``tx``: the bytes at its own rate, handed
        over frame by frame as each one's last byte arrives."""
        rx = group.rx
        heard: _Heard | _Transmission = tx if tx.baud == rx.baud else _Heard.of(tx, rx.baud)
        hd = heard.data
        n = len(hd)
        if n >= 6 and hd[0] == 0xFF and hd[1] == 0xFF and hd[2] != 0xFF and hd[3] + 4 == n:
            ends: Iterable[int] = (n,)  # one whole frame
        else:
            ends = frame_ends(hd)
        i0 = 0
        for end in ends:
            if end > i0:
                job = (group, heard, i0, end, source)
                heapq.heappush(
                    self._events, (heard.arrival(end - 1), next(self._seq), self._deliver, job)
                )
                rx.queued += 1
            i0 = end

    def _unheard(self, group: _Group, tx: _Transmission) -> bool:
        """Whether the whole frame ``tx``, a servo's status packet heard at its own rate,
        need not be delivered to ``group``: no other servo there has its ID, and it
        arrives at an idle receiver with nothing else due before it. ``_deliver`` would
        drop it unparsed; skipping it spares an event per reply. A collision can still
        damage the bytes, and then ``_collide`` delivers them after all."""
        rx = group.rx
        if rx.queued or rx.parser.state or group.epoch != self._link_epoch:
            return False
        data = tx.data
        if len(data) > MAX_PACKET_LEN:
            return False
        hearers = group.by_id.get(data[2])
        if hearers is None or len(hearers) != 1 or hearers[0] is not tx.source:
            return False
        tx.unheard = group
        return True

    def _collide(self, a: _Transmission, b: _Transmission) -> None:
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

    def _deliver_read(self, t: float, job: tuple[_Group, _Transmission]) -> None:
        """The master's READ frame, whole, to a group of C servos at its rate: when it
        comes to an idle receiver and is good, the servo it names answers in one C call
        (``_deliver`` would get there through more checks); anything else (a damaged
        frame, a receiver mid-packet, an ID change on the way, nobody with that ID)
        takes ``_deliver``."""
        group, tx = job
        size = self._c_read(group, tx.data, t)
        if not size:
            self._deliver(t, (group, tx, 0, 8, MASTER))
            return
        servo = self._read_answered(group, tx.data, size, t)
        if servo is not None:
            self._quiet_reply_out(group, servo, size, t)

    def _c_read(self, group: _Group, frame: bytes | bytearray, t: float) -> int:
        """The length of the status packet the C servos make of the READ ``frame`` heard
        at ``t`` (in ``_c_reply``), or 0 when the general path must take the frame."""
        index = group.c_by_id
        if group.rx.parser.state or group.epoch != self._link_epoch or index is None:
            return 0
        return lib.sim_servo_deliver_read(
            index, frame if type(frame) is bytes else bytes(frame), 8, t, self._c_reply, 256
        )

    def _read_answered(
        self, group: _Group, frame: bytes | bytearray, size: int, t: float
    ) -> VirtualServo | None:
        """The receiver's side of a READ the C servos answered (``_c_read``), and the
        status packet sent the general way unless the line is quiet; the servo that
        answers when it is (see ``_quiet_reply_out``), None otherwise."""
        rx = group.rx
        rx.queued -= 1
        rx.last_t = t
        servo = group.by_id[frame[2]][0]
        if (
            rx.queued
            or self._wire_end > t
            or self._groups is None
            or self._quiet_reply is not group
            or rx.baud != self.baudrate
        ):
            self._reply(servo, (self._c_reply_bytes[:size], servo.baudrate), t)
            return None
        return servo

    def _quiet_reply_out(self, group: _Group, servo: VirtualServo, size: int, t: float) -> None:
        """The usual case, what _reply and _transmit would do, in short: the line is
        quiet, no faults, one group at the master's rate and nothing else due to it, so
        the status packet meets nobody, the master hears it as sent, and the group
        would drop it unheard."""
        packet = self._c_reply_bytes[:size]  # bytes, as the master's READ
        reply = _Transmission(servo, t + servo.return_delay_s, group.rx.baud, packet)
        reply.unheard = group
        self._wire = [reply]
        self._wire_end = end = reply.end
        self._master_rx.append(reply)
        self._servo_tx_free[id(servo)] = end
        self.stats.replies += 1

    def _deliver_sync_write(self, t: float, job: tuple[_Group, _Transmission]) -> None:
        """The master's SYNC_WRITE frame, whole, to a group of C servos at its rate: a
        good one of goals (and speeds) that comes to an idle receiver is handled in one C
        call (what ``_deliver`` would do through more checks, the parse skipped);
        anything else takes ``_deliver``."""
        group, tx = job
        rx = group.rx
        index = group.c_by_id
        frame = tx.data
        if (
            rx.parser.state
            or group.epoch != self._link_epoch
            or index is None
            or lib.sim_servo_deliver_sync_write(
                index, frame if type(frame) is bytes else bytes(frame), len(frame), t
            )
        ):
            self._deliver(t, (group, tx, 0, len(frame), MASTER))
            return
        rx.queued -= 1
        rx.last_t = t

    def _deliver(self, t: float, job: tuple) -> None:
        group, heard, i0, i1, source = job
        if group.epoch != self._link_epoch:
            group.reindex(self._link_epoch)
        rx = group.rx
        rx.queued -= 1
        parser = rx.parser
        if parser.state and heard.arrival(i0) - rx.last_t > INTER_BYTE_GAP_S:
            parser.reset()
        rx.last_t = t
        data = heard.data
        n = i1 - i0
        if (
            n >= 6
            and not parser.state
            and data[i0] == 0xFF
            and data[i0 + 1] == 0xFF
            and data[i0 + 3] + 4 == n <= MAX_PACKET_LEN
        ):
            # One whole frame to an idle parser: it yields one packet (or a bad checksum)
            # for the ID in byte 2 and leaves the parser idle. When no servo here but the
            # sender answers to that ID (a status packet, a READ of another bus), nobody
            # acts on it, and the parse is skipped.
            target = data[i0 + 2]
            hearers = group.by_id.get(target)
            if target != BROADCAST_ID and target != 0xFF:
                if hearers is None or (len(hearers) == 1 and hearers[0] is source):
                    return
                frame = bytes(data[i0:i1])
                if n == 8 and group.c_by_id is not None:
                    # a READ, the commonest packet, goes to the C servo whole (checksum,
                    # status packet); the one servo with this ID is not the sender
                    out = self._c_reply
                    size = lib.sim_servo_deliver_read(group.c_by_id, frame, n, t, out, 256)
                    if size:
                        servo = hearers[0]
                        self._reply(servo, (ffi.buffer(out, size)[:], servo.baudrate), t)
                        return
                if ~sum(frame[2:-1]) & 0xFF == frame[-1]:
                    # a good packet for one ID: what the parser would yield, unparsed
                    code, params = frame[4], bytes(frame[5:-1])
                    for s in hearers:
                        if s is not source:
                            reply = s.handle(target, code, params, t)
                            if reply is not None:
                                self._reply(s, reply, t)
                    return
            elif (
                target == BROADCAST_ID and data[i0 + 4] == _SYNC_WRITE and group.c_by_id is not None
            ):
                # a SYNC_WRITE to C servos, once a tick in a closed loop: when good, what
                # the parser would yield goes to _sync_write unparsed (a tapped bus
                # still parses it, the general path the fast ones are tested against)
                frame = bytes(data[i0:i1])
                if ~sum(frame[2:-1]) & 0xFF == frame[-1]:
                    self._sync_write(group, frame[5:-1], t, source)
                    return
        for event in parser.feed(data[i0:i1]):  # a slice is a copy
            if group.epoch != self._link_epoch:  # the packet before changed an ID
                group.reindex(self._link_epoch)
            # a packet for one ID concerns only the servos with that ID (the others
            # ignore it); every servo looks at a damaged one
            if type(event) is not Packet:
                hearers = group.members
            elif event.id != BROADCAST_ID:
                hearers = group.by_id.get(event.id)
                if hearers is None:
                    continue
            elif event.code == _SYNC_WRITE:
                self._sync_write(group, event.params, t, source)
                continue
            else:
                hearers = group.members
            for s in hearers:
                if s is not source:
                    reply = s.receive(event, t)
                    if reply is not None:
                        self._reply(s, reply, t)

    @staticmethod
    def _sync_write(group: _Group, params: bytes, t: float, source: object) -> None:
        """A broadcast SYNC_WRITE, parsed once: each servo named gets its own block (the
        first that names it, as each servo looks for itself); the others ignore it."""
        shape = sync_write_shape(params)
        if shape is None:
            return  # malformed: no servo can find its slice
        index = group.c_by_id
        if index is not None and source is MASTER:
            if lib.sim_servo_sync_write(index, params, len(params), t) == 0:
                return  # goals (and speeds): all handled in C
        address, block = shape
        by_id = group.by_id
        done = set()
        for i in range(2, len(params), block):
            sid = params[i]
            servos = by_id.get(sid)
            if servos is None or sid in done:
                continue
            done.add(sid)
            for s in servos:
                if s is not source:
                    s.sync_write_block(address, params[i + 1 : i + block], t)

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
