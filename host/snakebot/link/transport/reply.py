"""One attempt of a transaction, as the reply is read: echo and stale replies told apart
from the awaited status packet, damaged and misshapen ones kept for the error, the
usual whole clean reply checked in a few comparisons, and "auto" echo settled by a
broadcast PING when the first exchange is ambiguous."""

from __future__ import annotations

from dataclasses import dataclass, field

from snakebot.formats import protocol
from snakebot.formats.protocol import BROADCAST_ID, Packet, Rejected
from snakebot.link.transport.client_state import ClientState
from snakebot.link.transport.timing import STATUS_OVERHEAD

RECENT_SENDS = 8
"""How many earlier instructions are remembered, so that their late echoes are recognised."""


def asked_for(sent: bytes, reply: Packet) -> bool:
    """Whether ``reply`` has the shape of the status packet the instruction ``sent`` asks
    for (a READ's length of data; none for the rest): from a client that timed out on an
    earlier request, a reply of another request's shape is its late answer, not a
    misshapen reply to the one it waits for."""
    instruction = next(iter(protocol.PacketParser().feed(sent)), None)
    if not isinstance(instruction, Packet) or instruction.id != reply.id:
        return False
    if instruction.code == protocol.Instruction.READ:
        return len(instruction.params) == 2 and instruction.params[1] == len(reply.params)
    return not reply.params


@dataclass
class Attempt:
    """What one attempt heard besides the reply it was waiting for."""

    echo_seen: bool = False
    echo: Packet | None = None  # the packet taken for our echo (identical to the instruction)
    rejected: list[Rejected] = field(default_factory=list)
    wrong_shape: list[Packet] = field(default_factory=list)
    stale: int = 0


CLEAN = Attempt()
"""What an attempt that heard nothing but its reply returns (shared; never changed)."""


def exact_reply(data: bytes, expect_id: int, expect_len: int) -> Packet | None:
    """``data`` as the status packet from ``expect_id`` with ``expect_len`` parameters if
    it is exactly that packet, intact; else None (and the parser decides what it is)."""
    if (
        data[0] != 0xFF
        or data[1] != 0xFF
        or data[2] != expect_id
        or data[3] != expect_len + 2
        or ~sum(data[2:-1]) & 0xFF != data[-1]
    ):
        return None
    return Packet(expect_id, data[4], data[5:-1])


class ReplyReader(ClientState):
    """Reading one attempt's reply (a part of
    :class:`~snakebot.link.transport.client.DxlClient`)."""

    def _attempt(
        self,
        packet: bytes,
        expect_id: int,
        expect_len: int,
        timeout: float,
        silence_s: float | None = None,
        sent: tuple[float, bytes] | None = None,
    ) -> tuple[Packet | None, Attempt]:
        parser = self._parser
        seen = CLEAN  # replaced by an Attempt of its own once anything else is heard
        echo = self._echo
        io = self._io
        parser.reset()
        if sent is None:
            io.flush_input()
            io.write(packet)
            start, data = io.clock(), b""
        else:
            start, data = sent
        deadline = start + timeout
        # Waiting for silence: bytes that may come back without a reply starting (our echo).
        unheard = len(packet) if echo is True else 0
        if silence_s is not None and silence_s < timeout:
            deadline = start + silence_s
        else:
            unheard = -1
        status_len = STATUS_OVERHEAD + expect_len
        while True:
            if data and seen is CLEAN:
                seen = Attempt()
            if unheard >= 0 and data:
                unheard -= len(data)
                if unheard < 0:  # a reply has begun: it gets its whole time
                    deadline = start + timeout
            for event in parser.feed(data) if data else ():
                if isinstance(event, Rejected):
                    seen.rejected.append(event)
                    continue
                if echo is not False:
                    raw = event.encode()
                    if not seen.echo_seen and raw == packet:
                        seen.echo_seen = True
                        seen.echo = event
                        continue
                    if echo is True and not seen.echo_seen:
                        seen.stale += 1  # heard before our own instruction: older than it
                        continue
                    if raw in self._recent:
                        seen.stale += 1  # the late echo of an earlier instruction
                        continue
                if event.id != expect_id:
                    seen.stale += 1
                    continue
                if len(event.params) != expect_len:
                    if any(asked_for(sent, event) for sent in self._recent):
                        seen.stale += 1  # the late answer to an earlier request
                    else:
                        seen.wrong_shape.append(event)
                    continue
                if echo is None:
                    self._echo = seen.echo_seen
                self._recent.append(packet)
                return event, seen
            remaining = deadline - io.clock()
            if remaining <= 0:
                self._recent.append(packet)
                return None, Attempt() if seen is CLEAN else seen
            # Read exactly what completes the reply (and our echo, if the line echoes and
            # it has not been heard yet): one read when all goes well. What arrives
            # beyond that is flushed before the next instruction.
            want = status_len - parser.pending
            if echo is True and not seen.echo_seen:
                want += len(packet)
            data = io.read(want if want > 1 else 1, remaining)
            if echo is False and len(data) == status_len and not parser.pending:
                # The usual case, the whole reply in one read: checked here in a few
                # comparisons instead of through the parser (same rules, same outcome).
                reply = exact_reply(data, expect_id, expect_len)
                if reply is not None:
                    self._recent.append(packet)
                    return reply, seen

    def _settle_echo(self, heard: Packet, expect_id: int, expect_len: int) -> Packet | None:
        """Decide an ambiguous first transaction in "auto" echo mode.

        The only packet heard was identical to the instruction: either the bus echoes
        and the servo was silent, or the bus does not echo and the servo's status happens
        to equal the instruction (PING answered with the input-voltage bit, for one).
        A broadcast PING, which no device answers, tells the two apart: only an echo
        brings it back. Returns the packet if it was the servo's reply, else None.
        """
        probe = protocol.ping(BROADCAST_ID)
        port = self._port
        port.reset_input_buffer()
        self._parser.reset()
        port.write(probe)
        self._recent.append(probe)
        wait = max(self.timing.reply_timeout_s(len(probe), 0), self.echo_probe_s)
        clock = self._io.clock
        deadline = clock() + wait
        heard_probe = False
        while not heard_probe:
            remaining = deadline - clock()
            if remaining <= 0:
                break
            port.timeout = self._read_timeout = remaining
            data = port.read(max(len(probe), port.in_waiting))
            heard_probe = any(
                isinstance(event, Packet) and event.encode() == probe
                for event in self._parser.feed(data)
            )
        self._echo = heard_probe
        if heard_probe or heard.id != expect_id or len(heard.params) != expect_len:
            return None
        return heard
