"""Finding servos on a bus: identify one (PING, then its model and firmware), or sweep IDs
over one or more baud rates with PINGs sent back to back and the replies parsed as one
stream; the line's echo detected, the quiet pauses timed from the wire."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import serial

from snakebot.facts import devices
from snakebot.formats import protocol
from snakebot.formats.protocol import (
    BROADCAST_ID,
    FRAME_RESET_S,
    CorruptPacket,
    DxlTimeout,
    ErrorFlags,
    Packet,
    PacketParser,
    Rejected,
)
from snakebot.formats.register_values import base_table, model_name
from snakebot.link.transport import DxlClient, settings, timing
from snakebot.link.transport.portio import PortIO

SCAN_RETRIES = 3


"""Further PINGs a scan gives an ID whose reply came back damaged."""

SCAN_MARGIN_S = 0.1e-3
"""The host margin of a silent ID's wait when ``SNAKEBOT_MARGIN_MS`` does not say. A host
that wakes late loses nothing (the reply waits in the port's buffer); the margin is for
a reply the transport delivers late (a program answering on a pseudo-terminal, an
adapter slower than its latency timer), and a scan needs little: a reply later than its
window still counts in the next ID's, and every ID still silent is PINGed once more at
the end. A transaction keeps the larger ``HOST_MARGIN_S``: a missed reply there is an
error."""


QUIET_READ_SIZE = 4096


"""Bytes one read of a quiet pause may drop (more than the line brings in the pause)."""


@dataclass(frozen=True)
class ServoInfo:
    """One servo found on the bus."""

    id: int
    baud: int
    model_number: int | None  # None when it answers PING but not READ
    model: str | None  # None when no device description has the model number
    firmware: int | None
    error: ErrorFlags  # the error bits of its PING reply

    @property
    def label(self) -> str:
        """The model in words: "AX-12A", "model 29", or "a device that answers PING only"."""
        if self.model_number is None:
            return "a device that answers PING only (Status Return Level 0?)"
        return self.model or f"model {self.model_number}"

    def as_dict(self) -> dict[str, object]:
        return {
            "id": self.id,
            "baud": self.baud,
            "model_number": self.model_number,
            "model": self.model,
            "firmware": self.firmware,
            "error": int(self.error),
            "error_text": self.error.describe(),
        }


def identify(client: DxlClient, servo_id: int, *, retries: int | None = None) -> ServoInfo | None:
    """PING ``servo_id`` and read its model and firmware; None if it does not answer.

    A servo reporting error bits (overheated, overloaded) is still identified: its
    flags are in :attr:`ServoInfo.error`. Damaged replies raise :class:`CorruptPacket`
    after the client's retries."""
    try:
        reply = client.ping(servo_id, check=False, retries=retries)
    except DxlTimeout:
        return None
    return _identified(client, servo_id, reply)


def _identified(client: DxlClient, servo_id: int, reply: Packet) -> ServoInfo:
    """The servo that answered PING with ``reply``: its model and firmware, read."""
    base = base_table()
    start = base.by_name("Model Number").address
    fw = base.by_name("Firmware Version")
    length = fw.address + fw.size - start
    try:
        data = client.transact(
            protocol.read(servo_id, start, length), servo_id, length, check=False
        ).params
    except DxlTimeout:  # answers PING only: Status Return Level 0
        return ServoInfo(servo_id, client.baudrate, None, None, None, reply.error)
    number = int.from_bytes(data[:2], "little")
    return ServoInfo(
        id=servo_id,
        baud=client.baudrate,
        model_number=number,
        model=model_name(number),
        firmware=data[fw.address - start],
        error=reply.error,
    )


@dataclass(frozen=True)
class Probe:
    """What one ID at one baud rate gave in a scan."""

    id: int
    baud: int
    info: ServoInfo | None  # None: nothing identified
    garbled: bool = False  # every try heard only damaged replies: something is there

    def as_dict(self) -> dict[str, object]:
        return {"id": self.id, "baud": self.baud}


def longest_return_delay_us() -> float:
    """The longest Return Delay Time any servo described can be set to (an AX-12's
    254 x 2 us), or the one snakebot is told to assume if that is longer: a scan knows
    nothing of the servos' settings, so it waits this long for each reply to begin."""
    longest = settings.resolve_return_delay_us()
    for name in devices.names("servo"):
        delay = devices.load(name).register("Return Delay Time")
        if delay.scale is not None and delay.max is not None:
            longest = max(longest, delay.max * float(delay.scale.factor))
    return longest


def scan_margin_s() -> float:
    """The host margin of a silent ID's wait: ``SNAKEBOT_MARGIN_MS``, else
    :data:`SCAN_MARGIN_S`."""
    return settings.resolve_margin_s(default=SCAN_MARGIN_S)


def silence_s(client: DxlClient) -> float:
    """How long after a PING leaves the host a scan takes a silent line for a missing
    servo: the PING on the wire, :func:`longest_return_delay_us`, the first byte of a
    status packet, the adapter's latency (the client's: what the adapter reports) and
    :func:`scan_margin_s`. It scales with the baud rate, so slow rates cost what their
    wire needs."""
    return timing.reply_timeout_s(
        len(protocol.ping(0)),
        1,
        client.baudrate,
        return_delay_us=longest_return_delay_us(),
        latency_s=client.timing.latency_s,
        margin_s=scan_margin_s(),
    )


def quiet_s() -> float:
    """How long a quiet pause lasts: the servos' frame reset and the scan's margin (the
    host may be late to send, never early, so the servos' pause is at least this)."""
    return FRAME_RESET_S + scan_margin_s()


def _quiet(
    port: serial.SerialBase, seconds: float, heard: Callable[[bytes], None] = lambda _: None
) -> None:
    """Send nothing for ``seconds`` (reading whatever arrives, for ``heard`` to look at,
    then dropping it), so every servo abandons a packet it was still waiting for.
    Waiting in a read, not a sleep, lets an emulated bus's clock run too."""
    deadline = time.monotonic() + seconds
    while (remaining := deadline - time.monotonic()) > 0:
        port.timeout = remaining
        heard(port.read(QUIET_READ_SIZE))
    port.reset_input_buffer()


def _client(port: serial.SerialBase, baud: int, echo: bool) -> DxlClient:
    """The scan's client: the host's margin even behind a pseudo-terminal (a program's
    would make every damaged reply, and the echo probe on a line without echo, cost half
    a second; a scan retries instead)."""
    margin = settings.resolve_margin_s(default=timing.HOST_MARGIN_S)
    return DxlClient(port, baud, echo=echo, margin_s=margin)


def detect_echo(port: serial.SerialBase, baud: int) -> bool:
    """Whether the line echoes the host's own bytes (a one-wire adapter), unless
    ``SNAKEBOT_ECHO`` says: a broadcast PING, which no servo answers, comes back only
    as its echo. Asked again (after a quiet pause) while what comes back is damaged.

    A scan settles this first because the client's own "auto" mode decides from the
    first answer, and on a noisy line a damaged echo can mislead it for the whole scan.
    """
    setting = settings.resolve_echo()
    if setting != "auto":
        return bool(setting)
    packet = protocol.ping(BROADCAST_ID)
    # an echo comes back before any reply would: the reply timeout covers it
    wait = _client(port, baud, False).timing.reply_timeout_s(len(packet), 0)
    for _ in range(1 + SCAN_RETRIES):
        port.reset_input_buffer()
        port.write(packet)
        heard = b""
        deadline = time.monotonic() + wait
        while (remaining := deadline - time.monotonic()) > 0 and len(heard) < len(packet):
            port.timeout = remaining
            heard += port.read(len(packet) - len(heard))
        if not heard:
            return False
        if heard == packet:
            return True
        _quiet(port, quiet_s())
    return True  # something came back every time, damaged: an echo on a noisy line


@dataclass
class _Heard:
    """What one PING's window brought: the PINGed servo's reply, whether a whole packet
    other than the echo came (a late reply, an answer to an earlier READ), and whether
    anything came back damaged or incomplete."""

    reply: Packet | None = None
    whole: bool = False
    trouble: bool = False


class _Sweep:
    """The PINGs of a scan at one rate, back to back, for :func:`scan_probes`.

    A silent ID (the rule) costs one write and a wait that ends when :func:`silence_s`
    says: no flush, no exception, no message. The line is parsed as one stream rather
    than flushed between IDs, and a PING reply counts for the ID it names as long as
    that ID's result has not been given: a reply that turns up windows after its own
    (an adapter later than its setting, a busy host, a program answering on a
    pseudo-terminal that is scheduled late) still finds its servo. An ID found so is
    given then; a silent one only once its second PING (below) has had the next ID's
    window too.

    An ID whose PING brings something damaged (a corrupted echo on a one-wire adapter,
    noise, a reply begun and never finished, two servos on one ID) gets up to
    :data:`SCAN_RETRIES` more, each after a quiet pause (:func:`quiet_s`): a damaged
    length byte leaves the servos waiting for the rest of a packet that never comes,
    and they give up on it only after a pause. If every try is damaged, the result is
    marked garbled: something is there.

    Every ID still silent at the end of the sweep is PINGed once more (and its result
    given then), so a servo whose PING or reply was lost to noise is not missed."""

    def __init__(self, client: DxlClient, silence: float, pings: Mapping[int, bytes]) -> None:
        self.client = client
        self.silence = silence
        self.pings = pings
        self.io = PortIO(client.port)
        self.parser = PacketParser()
        self.reply_timeout = client.timing.reply_timeout_s(len(protocol.ping(0)), 0)
        self.waiting: dict[int, None] = {}
        """The IDs PINGed at this rate, silent so far, whose result is not given yet."""
        self.late: list[Packet] = []
        """PING replies heard for IDs of :attr:`waiting`, not yet taken."""
        self.last: int | None = None
        """The ID PINGed last."""

    def run(self, ids: Sequence[int]) -> Iterator[Probe]:
        """Each of ``ids``' results, once: the silent ones after their second PING."""
        self.io.flush_input()
        yield from self._pass(ids, final=False)
        yield from self._pass([i for i in ids if i in self.waiting], final=True)
        for servo_id in list(self.waiting):  # none: each was given in the final pass
            yield self._given(servo_id)

    def _pass(self, ids: Sequence[int], *, final: bool) -> Iterator[Probe]:
        """One PING for each of ``ids`` still waiting (more where replies come back
        damaged). A silent ID stays waiting; in the ``final`` pass its result is given
        once the next ID's window is over."""
        previous: int | None = None  # silent so far; its reply may still come
        for servo_id in ids:
            if final and servo_id not in self.waiting:
                continue  # its reply to the first PING came late, in the meantime
            heard = self._listen(servo_id)
            if heard.trouble or heard.reply is not None:
                self.waiting.pop(servo_id, None)
            else:  # silent so far: a late reply to it counts from now on
                self.waiting[servo_id] = None
            yield from self._take_late(final)
            if heard.trouble:
                yield from self._settle(self._retry(servo_id), final)
                if previous is not None and previous in self.waiting:
                    del self.waiting[previous]  # the damage may have been its reply
                    yield from self._settle(self._retry(previous), final)
            elif heard.reply is not None:
                yield from self._settle(self._found(servo_id, heard.reply), final)
            else:
                if final and previous is not None and previous in self.waiting:
                    yield self._given(previous)
                previous = servo_id if servo_id in self.waiting else None
                continue
            # The result above came first, so a caller that counts the bytes heard and
            # sent between results charges the silent one below with none.
            if final and previous is not None and previous in self.waiting:
                yield self._given(previous)
            previous = None
        if final and previous is not None and previous in self.waiting:
            yield self._given(previous)

    def _given(self, servo_id: int) -> Probe:
        """The silent result of a waiting ID, given: no reply will count for it now."""
        del self.waiting[servo_id]
        return Probe(servo_id, self.client.baudrate, None)

    def _settle(self, probe: Probe, final: bool) -> Iterator[Probe]:
        """``probe``, unless it is silent and not ``final`` (the ID then waits for its
        second PING); then the late replies heard meanwhile."""
        if probe.info is None and not probe.garbled and not final:
            self.waiting[probe.id] = None
        else:
            yield probe
        yield from self._take_late(final)

    def _take_late(self, final: bool) -> Iterator[Probe]:
        """The servos of the late replies heard, each identified (which may hear more)."""
        while self.late:
            packet = self.late.pop(0)
            if packet.id in self.waiting:
                del self.waiting[packet.id]
                probe = self._found(packet.id, packet)
                if probe.info is None and not probe.garbled and not final:
                    self.waiting[probe.id] = None
                else:
                    yield probe

    def _hear(self, event: Packet | Rejected, servo_id: int, heard: _Heard) -> None:
        """One event of the stream, in the window of ``servo_id``'s PING."""
        if isinstance(event, Rejected):
            heard.trouble = True
            return
        heard.whole = True
        if event.id == servo_id:
            if event.params:  # no PING reply has parameters: not what it seems
                heard.trouble = True
            else:
                heard.reply = event
        elif event.id in self.waiting and not event.params:
            self.late.append(event)

    def _listen(self, servo_id: int) -> _Heard:
        """PING ``servo_id`` and listen until the silence window ends or, once a reply
        has begun, its whole reply timeout."""
        packet = self.pings[servo_id]
        self.io.write(packet)  # first: what follows is done while it is on the wire
        start = time.monotonic()
        self.last = servo_id
        io, parser, heard = self.io, self.parser, _Heard()
        echo_due = self.client.echo is True
        deadline = start + self.silence
        unheard = len(packet) if echo_due else 0  # bytes that may come back without a reply
        while (remaining := deadline - time.monotonic()) > 0:
            # exactly what completes a reply (and the echo): one read when all goes well
            want = timing.STATUS_OVERHEAD - parser.pending + (len(packet) if echo_due else 0)
            data = io.read(want if want > 1 else 1, remaining)
            if not data:
                continue
            unheard -= len(data)
            if unheard < 0:  # a reply has begun: it gets its whole time
                deadline = start + self.reply_timeout
            for event in parser.feed(data):
                if echo_due and isinstance(event, Packet) and event.encode() == packet:
                    echo_due = False  # our own PING: the first packet equal to it
                else:
                    self._hear(event, servo_id, heard)
            if heard.reply is not None:
                break
        # A missing echo means the PING itself may have been damaged; bytes beyond the
        # echo that made no whole packet are one damaged past recognition (a collision,
        # noise).
        heard.trouble |= echo_due or (unheard < 0 and not heard.whole)
        return heard

    def _identify(self, servo_id: int, reply: Packet) -> ServoInfo | None:
        """The servo that answered with ``reply``, its model read through the client
        (which flushes the line, so the parser starts afresh: what has come is heard
        first, late replies among it); None if that read kept coming back damaged."""
        self._drain(servo_id)
        try:
            return _identified(self.client, servo_id, reply)
        except CorruptPacket:
            return None
        finally:
            self.parser.reset()

    def _drain(self, servo_id: int) -> None:
        """Hear what has arrived and not been read; while the ID PINGed last is still
        silent, what comes within one more window too (a late reply to it is due then:
        the READ after would take it for a stray packet and drop it)."""
        wait = 0.0 if self._last_heard() else self.silence
        deadline = time.monotonic() + wait
        while True:
            self._feed(self.io.read(QUIET_READ_SIZE, wait), servo_id)
            wait = deadline - time.monotonic()
            if wait <= 0 or self._last_heard():
                return

    def _last_heard(self) -> bool:
        """Whether the ID PINGed last has a result or a reply waiting to be taken."""
        last = self.last
        return last not in self.waiting or any(p.id == last for p in self.late)

    def _feed(self, data: bytes, servo_id: int) -> None:
        """Hear ``data`` outside a window: only late replies count."""
        for event in self.parser.feed(data):
            self._hear(event, servo_id, _Heard())

    def _found(self, servo_id: int, reply: Packet) -> Probe:
        info = self._identify(servo_id, reply)
        if info is None:
            return self._retry(servo_id)
        return Probe(servo_id, self.client.baudrate, info)

    def _retry(self, servo_id: int) -> Probe:
        """The further tries of an ID whose PING (or identifying READ) came back damaged."""
        client = self.client
        for _ in range(SCAN_RETRIES):
            # late replies that come in the pause still count; then a flush
            _quiet(client.port, quiet_s(), lambda data: self._feed(data, servo_id))
            self.parser.reset()
            heard = self._listen(servo_id)
            if heard.trouble:
                continue
            if heard.reply is None:
                return Probe(servo_id, client.baudrate, None)
            info = self._identify(servo_id, heard.reply)
            if info is not None:
                return Probe(servo_id, client.baudrate, info)
        return Probe(servo_id, client.baudrate, None, garbled=True)


def scan_probes(
    port: serial.SerialBase, ids: Iterable[int], bauds: Sequence[int]
) -> Iterator[Probe]:
    """PING every ID in ``ids`` at each rate in ``bauds`` and identify the servos that
    answer (:class:`_Sweep` says how), yielding each result as it comes, so a caller
    can show progress and keep what was found if stopped."""
    ids = list(ids)
    pings = {servo_id: protocol.ping(servo_id) for servo_id in ids}
    echo = detect_echo(port, bauds[0]) if bauds else False
    for n, baud in enumerate(bauds):
        client = _client(port, baud, echo)
        if n:  # servos at this rate heard the last one's PINGs as garbage: let them reset
            _quiet(port, quiet_s())
        yield from _Sweep(client, silence_s(client), pings).run(ids)


@dataclass
class ScanReport:
    """What a scan of ``ids`` at ``bauds`` on ``port`` has found so far: the servos
    identified, the IDs that gave only damaged replies, and whether it was stopped."""

    port: str
    ids: list[int]
    bauds: list[int]
    found: list[ServoInfo] = field(default_factory=list)
    garbled: list[Probe] = field(default_factory=list)
    interrupted: bool = False

    def add(self, probe: Probe) -> None:
        if probe.info is not None:
            # by rate, then ID, whichever pass found it (a servo the retry pass finds
            # comes back late)
            self.found = in_scan_order([*self.found, probe.info], self.bauds)
        elif probe.garbled:
            self.garbled.append(probe)

    def as_dict(self) -> dict[str, object]:
        return {
            "port": self.port,
            "ids": self.ids,
            "bauds": self.bauds,
            "found": [s.as_dict() for s in self.found],
            "garbled": [g.as_dict() for g in self.garbled],
            "interrupted": self.interrupted,
        }


def scan_into(
    report: ScanReport,
    port: serial.SerialBase,
    seen: Callable[[Probe], None] = lambda _: None,
) -> ScanReport:
    """Scan ``report``'s IDs and rates on the open ``port`` (:func:`scan_probes`), adding
    each result to ``report`` as it comes and then handing it to ``seen``. Stopped by
    Ctrl-C, ``report`` keeps what was found and says it was interrupted; the
    KeyboardInterrupt goes on."""
    try:
        for probe in scan_probes(port, report.ids, report.bauds):
            report.add(probe)
            seen(probe)
    except KeyboardInterrupt:
        report.interrupted = True
        raise
    return report


def in_scan_order(servos: Iterable[ServoInfo], bauds: Sequence[int]) -> list[ServoInfo]:
    """``servos`` by their rate's place in ``bauds``, then by ID."""
    place = {baud: k for k, baud in enumerate(bauds)}
    return sorted(servos, key=lambda s: (place.get(s.baud, len(place)), s.id))


def scan(port: serial.SerialBase, ids: Iterable[int], bauds: Sequence[int]) -> list[ServoInfo]:
    """The servos :func:`scan_probes` identifies, by rate (in ``bauds``' order), then ID."""
    found = [p.info for p in scan_probes(port, ids, bauds) if p.info is not None]
    return in_scan_order(found, bauds)
