"""The master's port on the bus: what the transports (a pseudo-terminal, a Unix socket,
``sim://``) and the controller emulator call to write, wait for and read bytes in
virtual time. A READ on a quiet line is held rather than put on the wire at once, and
a timed read of its status packet (:meth:`MasterPort.master_receive`) takes it whole
in a few steps; anything else in between releases it to the general path first, so
the outcome is the same."""

from __future__ import annotations

import heapq
import math

from snakebot.sim.bus.clock import BITS_PER_BYTE
from snakebot.sim.bus.state import BusState
from snakebot.sim.bus.wire import MASTER, READ_CODE, SYNC_WRITE_CODE, Transmission


class MasterPort(BusState):
    """The master's side of the line (a part of :class:`~snakebot.sim.bus.bus.Bus`)."""

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
            if code == READ_CODE and n == 8:
                # held (see _release): its transmission and delivery event are made
                # only if something other than master_receive comes first
                end = start + n * (BITS_PER_BYTE / group.rx.baud)  # as Transmission
                self._held = (start, end, next(self._seq), group, frame)
                self._wire_end = end
            else:
                tx = Transmission(MASTER, start, group.rx.baud, frame)
                self._put_on_wire(tx)
                end = tx.end
                if code == SYNC_WRITE_CODE:
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

    def _release(self) -> None:
        """The held READ (``master_write``) as the bus would have it had it not been
        held: on the wire, its delivery due at its end (in its place in the order)."""
        start, end, seq, group, frame = self._held
        self._held = None
        tx = Transmission(MASTER, start, group.rx.baud, frame)
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

    def master_coming(self, before: float, limit: int) -> tuple[bytes, list[float], float | None]:
        """What :meth:`master_read` will give byte by byte of the streams on their way to
        the master, as long as nothing else is put on the wire: their unread bytes that
        are complete before ``before`` (at most ``limit``), when each is, and when the
        next one after them is (None: no more). Several streams (two replies back to
        back, a collision, an echo) merge by arrival, as :meth:`master_read` merges them."""
        streams = self._master_rx
        if len(streams) > 1:
            return self._coming_merged(before, limit)
        if not streams:
            return b"", [], None
        h = streams[0]
        n = len(h.data)
        end = h.pos
        times = []
        while end < n and end - h.pos < limit:
            t = h.arrival(end)
            if not t < before:
                break
            times.append(t)
            end += 1
        return bytes(h.data[h.pos : end]), times, (h.arrival(end) if end < n else None)

    def _coming_merged(self, before: float, limit: int) -> tuple[bytes, list[float], float | None]:
        """:meth:`master_coming` of several streams: their unread bytes in the order
        :meth:`master_read` takes them (by arrival, then stream, then place)."""
        streams = self._master_rx
        coming = sorted(
            (h.arrival(i), n, i) for n, h in enumerate(streams) for i in range(h.pos, len(h.data))
        )
        k = 0
        while k < len(coming) and k < limit and coming[k][0] < before:
            k += 1
        data = bytes(streams[n].data[i] for _, n, i in coming[:k])
        return data, [t for t, _, _ in coming[:k]], (coming[k][0] if k < len(coming) else None)

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
                t, (group, Transmission(MASTER, start, group.rx.baud, frame), 0, 8, MASTER)
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
