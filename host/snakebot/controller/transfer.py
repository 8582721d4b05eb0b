"""Streaming WRITE packets to a device with several in flight, counting acknowledgements.

Stop-and-wait leaves the wire idle for a round trip per packet, and a USB-serial adapter
makes that round trip long (its latency timer). The PC link is full duplex, so up to
``window`` WRITEs go out before the first is acknowledged, and each acknowledgement
releases the next one: the host-to-controller wire stays busy.

The controller handles packets in order and answers each intact WRITE with an identical
empty status packet; a damaged packet gets no answer at all. So acknowledgements can
be counted but not told apart: ``acked == sent`` proves that every packet arrived, and a
shortfall proves that some did not, without saying which. The caller therefore resends
the whole stream after a shortfall, which the upload protocol makes safe (each chunk
carries its own offset, and a commit checks the length and CRC of what was staged).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from snakebot.protocol import Packet, PacketParser, Rejected
from snakebot.transport import DxlClient, wire_time_s
from snakebot.transport.timing import STATUS_OVERHEAD

READ_SLICE_S = 0.02
"""Longest single blocking read while waiting, so deadlines are checked this often."""


@dataclass
class StreamResult:
    """What one pass over the packets achieved."""

    sent: int = 0
    acked: int = 0
    error: int = 0  # the error byte of the first acknowledgement that carried one
    error_at: int = -1  # its position among the acknowledgements
    damaged: int = 0  # damaged packets heard coming back
    foreign: int = 0  # intact packets that were not our acknowledgements
    seconds: float = 0.0  # first byte written to last acknowledgement (or the give-up)

    @property
    def complete(self) -> bool:
        return self.error == 0 and self.acked == self.sent


def stream_writes(
    link: DxlClient,
    device_id: int,
    packets: Sequence[bytes],
    window: int,
    on_ack: Callable[[int], None] | None = None,
) -> StreamResult:
    """Send ``packets`` (WRITEs to ``device_id``) with at most ``window`` unacknowledged.

    Stops at the first acknowledgement with error bits (nothing after it is sent), or
    when no acknowledgement came within the time the packets in flight need on the wire
    plus the link's latency and margin. ``on_ack(n)`` is called with the running count.
    """
    port = link.port
    timing = link.timing
    parser = PacketParser()
    result = StreamResult()
    in_flight: deque[int] = deque()  # lengths of the unacknowledged packets, oldest first
    saved_timeout = port.timeout
    port.reset_input_buffer()
    port.timeout = READ_SLICE_S
    start = time.monotonic()
    last_progress = start
    try:
        while True:
            while result.sent < len(packets) and len(in_flight) < window and not result.error:
                packet = packets[result.sent]
                port.write(packet)
                in_flight.append(len(packet))
                result.sent += 1
                last_progress = time.monotonic()
            if not in_flight:
                break
            # the oldest packet's reply is due once everything in flight has crossed the
            # wire and its status (and those of the others) has come back
            due = timing.reply_timeout_s(sum(in_flight), 0) + wire_time_s(
                STATUS_OVERHEAD * (len(in_flight) - 1), timing.baudrate
            )
            want = max(1, STATUS_OVERHEAD - parser.pending, port.in_waiting)
            events = parser.feed(port.read(want))
            now = time.monotonic()
            for event in events:
                if isinstance(event, Rejected):
                    result.damaged += 1
                elif isinstance(event, Packet) and event.id == device_id and not event.params:
                    if in_flight:
                        in_flight.popleft()
                    result.acked += 1
                    last_progress = now
                    if event.code and not result.error:
                        result.error, result.error_at = event.code, result.acked - 1
                    if on_ack is not None:
                        on_ack(result.acked)
                else:
                    result.foreign += 1
            if result.error and not in_flight:
                break
            if now - last_progress > due:
                break  # what is missing is not coming
    finally:
        result.seconds = time.monotonic() - start
        port.timeout = saved_timeout
    return result
