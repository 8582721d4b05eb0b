"""Streaming packets to a device with several in flight: WRITEs and READs in one stream.

Stop-and-wait leaves the wire idle for a round trip per packet, and a USB-serial adapter
makes that round trip long (its latency timer). The PC link is full duplex, so up to
``window`` packets go out before the first is answered, and each answer releases the
next one: the host-to-controller wire stays busy while the answers come back on the other.

The controller handles packets in order and answers each intact one; a damaged packet
gets no answer at all. So an answer belongs to the oldest packet in flight that it can
answer (a READ's status carries the bytes asked for, a WRITE's none; an error status
with no bytes answers either), and the packets before that one were lost. WRITE
acknowledgements are identical, so after a lost WRITE the next one's acknowledgement is
taken for it and the shortfall shows at the end: ``acked == sent`` proves that every
packet arrived, a shortfall proves that some did not, without always saying which. The
caller then sends again, which the upload protocol makes safe (each chunk carries its own
offset, and a commit checks the length and CRC of what was staged).

An :class:`Ask` may check its answer as it arrives (raising stops the stream), may ask
for more packets to be sent next, and may be held back until the caller says it is
ready: that is how an upload's checks travel with its first chunks while its commit
waits for their answers.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from snakebot.formats.protocol import Packet, PacketParser, Rejected
from snakebot.link.transport import DxlClient, wire_time_s
from snakebot.link.transport.timing import STATUS_OVERHEAD

READ_SLICE_S = 0.02
"""Longest single blocking read while waiting, so deadlines are checked this often."""


@dataclass(frozen=True, eq=False)
class Ask:
    """One packet of a stream and the answer it waits for."""

    packet: bytes
    reply_params: int = 0
    """Parameter bytes its status packet carries: a READ's length, 0 for a WRITE or PING."""
    on_reply: Callable[[Packet], Sequence[Ask]] | None = None
    """Called with its status packet, error bits and all. It raises to stop the stream, or
    returns asks to send next."""
    ready: Callable[[], bool] | None = None
    """Holds this ask, and those after it, until it returns True: a stream with nothing
    left in flight and this still False stops there (``StreamResult.held``)."""
    follows: bool = False
    """Sent right after the ask before it: asks that an answer adds go after it, not
    between the two (a READ of a window page after the WRITE that shows the page)."""


@dataclass
class StreamResult:
    """What one pass over the packets achieved."""

    sent: int = 0
    acked: int = 0  # answers matched to a packet
    total: int = 0  # packets the stream had to send, added ones included
    error: int = 0  # the error byte of the first answer that stopped the stream
    error_at: int = -1  # the position, in sending order, of the packet it answered
    error_ask: Ask | None = None  # that packet
    lost: int = 0  # packets passed over by the answer of a later one
    damaged: int = 0  # damaged packets heard coming back
    foreign: int = 0  # intact packets that answered nothing in flight
    held: bool = False  # stopped at an ask that was never ready
    sent_bytes: int = 0
    seconds: float = 0.0  # first byte written to last answer (or the give-up)

    @property
    def complete(self) -> bool:
        return self.error == 0 and not self.held and self.acked == self.sent == self.total


def _answers(ask: Ask, reply: Packet) -> bool:
    return len(reply.params) == ask.reply_params or (reply.code != 0 and not reply.params)


def stream(
    link: DxlClient,
    device_id: int,
    asks: Sequence[Ask],
    window: int,
    on_ack: Callable[[int], None] | None = None,
) -> StreamResult:
    """Send ``asks`` (packets to ``device_id``) with at most ``window`` unanswered.

    Stops at the first answer with error bits (nothing after it is sent), at an ask that
    is not ready once nothing is in flight, or when no answer came within the time the
    packets in flight need on the wire plus the link's latency and margin. An exception
    from ``on_reply`` stops the sending too; it is raised once what was in flight has come
    back (or is overdue), so the next exchange does not hear it. ``on_ack(n)`` is called
    with the running count of answers.
    """
    port = link.port
    timing = link.timing
    parser = PacketParser()
    result = StreamResult(total=len(asks))
    unsent: deque[Ask] = deque(asks)
    in_flight: deque[Ask] = deque()
    failure: BaseException | None = None
    saved_timeout = port.timeout
    port.reset_input_buffer()
    port.timeout = READ_SLICE_S
    start = time.monotonic()
    last_progress = start

    def stopping() -> bool:
        return bool(result.error) or failure is not None

    def add(more: Sequence[Ask]) -> None:
        at = 0
        while at < len(unsent) and unsent[at].follows:
            at += 1
        for offset, ask in enumerate(more):
            unsent.insert(at + offset, ask)
        result.total += len(more)

    try:
        while True:
            while unsent and len(in_flight) < window and not stopping():
                ask = unsent[0]
                if ask.ready is not None and not ask.ready():
                    break
                port.write(ask.packet)
                unsent.popleft()
                in_flight.append(ask)
                result.sent += 1
                result.sent_bytes += len(ask.packet)
                last_progress = time.monotonic()
            if not in_flight:
                result.held = bool(unsent) and not stopping()
                break
            # the oldest packet's answer is due once everything in flight has crossed the
            # wire and its status (and those of the others) has come back
            due = timing.reply_timeout_s(sum(len(a.packet) for a in in_flight), 0) + wire_time_s(
                STATUS_OVERHEAD * (len(in_flight) - 1) + sum(a.reply_params for a in in_flight),
                timing.baudrate,
            )
            want = max(1, STATUS_OVERHEAD - parser.pending, port.in_waiting)
            events = parser.feed(port.read(want))
            now = time.monotonic()
            for event in events:
                if isinstance(event, Rejected):
                    result.damaged += 1
                    continue
                if not isinstance(event, Packet) or event.id != device_id:
                    result.foreign += 1
                    continue
                match = next((i for i, a in enumerate(in_flight) if _answers(a, event)), None)
                if match is None:
                    result.foreign += 1
                    continue
                for _ in range(match):
                    in_flight.popleft()
                result.lost += match
                ask = in_flight.popleft()
                position = result.sent - len(in_flight) - 1
                result.acked += 1
                last_progress = now
                if event.code and not result.error:
                    result.error, result.error_at, result.error_ask = event.code, position, ask
                if ask.on_reply is not None and failure is None:
                    try:
                        add(ask.on_reply(event))
                    except Exception as exc:  # the caller's check said no: stop sending
                        failure = exc
                if on_ack is not None:
                    on_ack(result.acked)
            if stopping() and not in_flight:
                break
            if now - last_progress > due:
                break  # what is missing is not coming
    finally:
        result.seconds = time.monotonic() - start
        port.timeout = saved_timeout
    if failure is not None:
        raise failure
    return result


def stream_writes(
    link: DxlClient,
    device_id: int,
    packets: Sequence[bytes],
    window: int,
    on_ack: Callable[[int], None] | None = None,
) -> StreamResult:
    """:func:`stream` of ``packets`` that are answered with no parameters (WRITEs, PINGs)."""
    return stream(link, device_id, [Ask(p) for p in packets], window, on_ack)
