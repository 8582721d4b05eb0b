"""Delivery: what each group of servos hears of a transmission and when (a packet is
handed over when its last byte has arrived), the servos' handling of it, and their
status packets sent back onto the wire. The commonest packets take short ways to the C
servos: a READ answered in one C call, a SYNC_WRITE of goals applied in one, a status
packet nobody else would act on not delivered at all; each does what the general path
(``Delivery._deliver``, through the shared receiver) would."""

from __future__ import annotations

import heapq
from collections.abc import Iterable

from snakebot.core import ffi, lib
from snakebot.formats.protocol import (
    BROADCAST_ID,
    FRAME_RESET_S,
    MAX_PACKET_LEN,
    Packet,
)
from snakebot.sim.bus.listeners import Group
from snakebot.sim.bus.state import BusState
from snakebot.sim.bus.wire import MASTER, SYNC_WRITE_CODE, Heard, Transmission
from snakebot.sim.servo.fast import VirtualServo
from snakebot.sim.servo.packets import sync_write_shape

INTER_BYTE_GAP_S = FRAME_RESET_S
"""A pause longer than this inside a packet makes a servo drop the partial packet."""


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


class Delivery(BusState):
    """What the servos hear and how they answer (a part of
    :class:`~snakebot.sim.bus.bus.Bus`)."""

    def _schedule(self, group: Group, tx: Transmission, source: object) -> None:
        """Schedule what ``group`` hears of ``tx``: the bytes at its own rate, handed
        over frame by frame as each one's last byte arrives."""
        rx = group.rx
        heard: Heard | Transmission = tx if tx.baud == rx.baud else Heard.of(tx, rx.baud)
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

    def _unheard(self, group: Group, tx: Transmission) -> bool:
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

    def _deliver_read(self, t: float, job: tuple[Group, Transmission]) -> None:
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

    def _c_read(self, group: Group, frame: bytes | bytearray, t: float) -> int:
        """The length of the status packet the C servos make of the READ ``frame`` heard
        at ``t`` (in ``_c_reply``), or 0 when the general path must take the frame."""
        index = group.c_by_id
        if group.rx.parser.state or group.epoch != self._link_epoch or index is None:
            return 0
        return lib.sim_servo_deliver_read(
            index, frame if type(frame) is bytes else bytes(frame), 8, t, self._c_reply, 256
        )

    def _read_answered(
        self, group: Group, frame: bytes | bytearray, size: int, t: float
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

    def _quiet_reply_out(self, group: Group, servo: VirtualServo, size: int, t: float) -> None:
        """The usual case, what _reply and _transmit would do, in short: the line is
        quiet, no faults, one group at the master's rate and nothing else due to it, so
        the status packet meets nobody, the master hears it as sent, and the group
        would drop it unheard."""
        packet = self._c_reply_bytes[:size]  # bytes, as the master's READ
        reply = Transmission(servo, t + servo.return_delay_s, group.rx.baud, packet)
        reply.unheard = group
        self._wire = [reply]
        self._wire_end = end = reply.end
        self._master_rx.append(reply)
        self._servo_tx_free[id(servo)] = end
        self.stats.replies += 1

    def _deliver_sync_write(self, t: float, job: tuple[Group, Transmission]) -> None:
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
                target == BROADCAST_ID
                and data[i0 + 4] == SYNC_WRITE_CODE
                and group.c_by_id is not None
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
            elif event.code == SYNC_WRITE_CODE:
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
    def _sync_write(group: Group, params: bytes, t: float, source: object) -> None:
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
