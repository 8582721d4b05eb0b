"""A Protocol 1.0 master on a serial port: one instruction out, at most one status back.

What makes a transaction trustworthy on a real bus:

* The input is flushed before each instruction, so bytes left over from earlier traffic
  are never read as this reply.
* On a one-wire (half-duplex) adapter the host hears its own instruction. That echo is
  recognised by comparing it with the bytes just sent and is skipped; with echo on,
  anything heard *before* the echo is older than the instruction and is discarded too.
  An echoed READ therefore never passes for the servo's reply (it has the same shape as
  one: READ's code 0x02 reads as the "angle limit" error bit, its two parameters as data).
* A status packet from an earlier, timed-out transaction that arrives late is discarded
  unless it comes from the addressed ID with the parameter length this instruction
  expects.
* Timed-out and corrupt replies are retried, and so are replies whose CHECKSUM or
  INSTRUCTION bit says the servo received a damaged instruction (it did nothing, so
  sending it again is safe); other error bits raise :class:`ServoError` at once, carrying
  the flags. After the last attempt the caller gets :class:`DxlTimeout`,
  :class:`CorruptPacket` or :class:`ServoError`.
* The 8-bit checksum lets about one damaged packet in 256 through. So a value read is
  checked against its register's range in the device description and read again when it
  is outside (then :class:`CorruptPacket`), and :meth:`DxlClient.read_confirmed` reads
  twice, for values that decisions are based on.
* Broadcast instructions and SYNC_WRITE get no reply and are not waited for; nor are
  instructions that the servo's Status Return Level tells it not to answer.
"""

from __future__ import annotations

import functools
import threading
import time
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import TracebackType

import serial

from snakebot.facts import devices
from snakebot.facts.devices import Device
from snakebot.formats import protocol
from snakebot.formats.protocol import (
    BROADCAST_ID,
    CorruptPacket,
    DxlTimeout,
    ErrorFlags,
    Instruction,
    Packet,
    PacketArgumentError,
    PacketParser,
    ProtocolError,
    Rejected,
    ServoError,
)
from snakebot.formats.protocol.instructions import HEADER
from snakebot.link.transport import settings
from snakebot.link.transport.portio import PortIO
from snakebot.link.transport.ports import open_port
from snakebot.link.transport.settings import EchoSetting
from snakebot.link.transport.timing import DEFAULT_BAUDRATE, STATUS_OVERHEAD, BusTiming

DEFAULT_STATUS_RETURN_LEVEL = 2
"""Factory setting: every instruction addressed to one servo is answered."""

RESEND_FLAGS = ErrorFlags.CHECKSUM | ErrorFlags.INSTRUCTION
"""Status error bits saying the servo did not act on the instruction because it arrived
damaged: the instruction is sent again, like after a damaged reply."""

_RESEND_MASK = int(RESEND_FLAGS)  # a plain int: IntFlag's & costs a Python call per reply

RECENT_SENDS = 8
"""How many earlier instructions are remembered, so that their late echoes are recognised."""

READ_PLANS = 4096
"""How many (servo, address, length) READs a client keeps ready-made (packet, timeout,
expected reply header, range checks); more are made again as needed."""

_INTACT_SUM = (sum(HEADER) + 0xFF) & 0xFF
"""The low byte of the sum of every byte of an intact packet: the header's, plus ID to
CHECKSUM, which the checksum makes 0xFF (mod 256). One sum checks a whole reply."""

_NEEDS_LEVEL = {
    Instruction.PING: 0,
    Instruction.READ: 1,
    Instruction.WRITE: 2,
    Instruction.REG_WRITE: 2,
    Instruction.ACTION: 2,
    Instruction.RESET: 2,
}


@functools.cache
def _instruction_name(code: int) -> str:
    try:
        return Instruction(code).name
    except ValueError:
        return f"instruction 0x{code:02X}"


@dataclass
class _Attempt:
    """What one attempt heard besides the reply it was waiting for."""

    echo_seen: bool = False
    echo: Packet | None = None  # the packet taken for our echo (identical to the instruction)
    rejected: list[Rejected] = field(default_factory=list)
    wrong_shape: list[Packet] = field(default_factory=list)
    stale: int = 0


_CLEAN = _Attempt()
"""What an attempt that heard nothing but its reply returns (shared; never changed)."""

_RangeCheck = tuple[str, int, int, bool, int, int]
"""(register name, offset in the data read, size, signed, lowest, highest)."""


@dataclass(frozen=True, slots=True)
class _ReadPlan:
    """Everything a READ of one (servo, address, length) needs, made once: a control
    loop reads the same registers of the same servos over and over."""

    packet: bytes  # the instruction
    servo_id: int
    length: int
    timeout: float  # the reply timeout for this instruction and reply
    reply_len: int  # the whole status packet
    head: bytes  # a clean reply's bytes before its data: header, ID, LEN, no error bits
    checks: list[_RangeCheck]  # the registers with a range within the bytes read


class DxlClient:
    """A Protocol 1.0 client for Dynamixel AX-12 servos (and any device speaking 1.0).

    ``port`` is a device path or pyserial URL (opened here, closed by :meth:`close`) or an
    open ``serial.Serial`` (used as is and left open). Keywords not given fall back to the
    environment (``SNAKEBOT_RETRIES``, ``SNAKEBOT_LATENCY_MS``, ``SNAKEBOT_MARGIN_MS``,
    ``SNAKEBOT_RETURN_DELAY_US``, ``SNAKEBOT_ECHO``) and then to the named defaults in
    :mod:`snakebot.link.transport.settings` and :mod:`snakebot.link.transport.timing`.

    ``echo``: True for a bus that echoes every instruction, False for one that never
    does, "auto" to find out from the first answered transaction. If that first exchange
    is ambiguous (the only packet heard equals the instruction) "auto" sends one
    broadcast PING, which no device answers, and waits at least ``echo_probe_s`` for
    its echo. Until it has decided, a packet identical to the instruction is never taken
    for the reply.
    ``status_return_level``: what every servo is assumed to be set to (default 2);
    change one servo's with :meth:`set_status_return_level`. Writes to the Status Return
    Level register made through this client update it automatically.
    ``device``: the kind of device on this port (an AX-12A unless told otherwise, e.g.
    ``snakebot.facts.devices.controller()`` on the PC link): where its Status Return Level
    and Model Number live comes from its description.
    ``check_ranges``: whether every value read is checked against its register's range
    in the device description (default True).

    Transactions from several threads are serialised. The client sets the port's read
    timeout itself, so a port handed in should not be read by anyone else meanwhile.
    """

    def __init__(
        self,
        port: str | serial.SerialBase,
        baudrate: int | None = None,
        *,
        retries: int | None = None,
        return_delay_us: float | None = None,
        latency_s: float | None = None,
        margin_s: float | None = None,
        echo: EchoSetting | None = None,
        echo_probe_s: float | None = None,
        status_return_level: int = DEFAULT_STATUS_RETURN_LEVEL,
        device: Device | None = None,
        check_ranges: bool = True,
    ) -> None:
        self.retries = settings.resolve_retries(retries)
        echo_setting = settings.resolve_echo(echo)
        self.echo_probe_s = settings.resolve_echo_probe_s(echo_probe_s)
        timing_kwargs = {
            "return_delay_us": settings.resolve_return_delay_us(return_delay_us),
            "latency_s": settings.resolve_latency_s(latency_s),
            "margin_s": settings.resolve_margin_s(margin_s),
        }
        self._default_level = _check_level(status_return_level)
        self._levels: dict[int, int] = {}
        self.device = device or devices.ax12()
        self._level_address = self.device.status_return_level_address
        self.check_ranges = check_ranges
        self._range_checks: dict[tuple[int, int], list[_RangeCheck]] = {}
        if isinstance(port, str):
            self._port = open_port(port, baudrate or DEFAULT_BAUDRATE, timeout=0)
            self._owns_port = True
        else:
            self._port = port
            self._owns_port = False
            if baudrate is not None and port.baudrate != baudrate:
                port.baudrate = baudrate
        self._io = PortIO(self._port)
        self.timing = BusTiming(baudrate=int(self._port.baudrate), **timing_kwargs)
        # None: not known yet ("auto" before the first answered transaction).
        self._echo: bool | None = None if echo_setting == "auto" else bool(echo_setting)
        self._parser = PacketParser()
        self._recent: deque[bytes] = deque(maxlen=RECENT_SENDS)
        self._read_timeout: float | None = None
        self._lock = threading.RLock()  # one transaction on the wire at a time

    @property
    def timing(self) -> BusTiming:
        """The bus's timing terms; assigning new ones applies them to every later
        transaction."""
        return self._timing

    @timing.setter
    def timing(self, timing: BusTiming) -> None:
        self._timing = timing
        # both hold timeouts computed from the timing
        self._timeouts: dict[tuple[int, int], float] = {}
        self._read_plans: dict[tuple[int, int, int], _ReadPlan] = {}

    # -- the port -----------------------------------------------------------------------

    @property
    def port(self) -> serial.SerialBase:
        """The underlying pyserial port."""
        return self._port

    @property
    def baudrate(self) -> int:
        return self.timing.baudrate

    @property
    def echo(self) -> bool | None:
        """Whether the bus echoes instructions: True, False, or None while "auto" has not
        decided yet."""
        return self._echo

    def close(self) -> None:
        """Close the port if this client opened it."""
        if self._owns_port:
            self._port.close()

    def __enter__(self) -> DxlClient:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- Status Return Level --------------------------------------------------------------

    def status_return_level(self, servo_id: int) -> int:
        """The Status Return Level this client assumes for ``servo_id``."""
        return self._levels.get(servo_id, self._default_level)

    def set_status_return_level(self, servo_id: int, level: int) -> None:
        """Tell the client what ``servo_id`` is set to (broadcast ID: every servo). This
        does not write the servo; write its Status Return Level register for that."""
        level = _check_level(level)
        if servo_id == BROADCAST_ID:
            self._default_level = level
            self._levels.clear()
        else:
            self._levels[servo_id] = level

    def _answers(self, servo_id: int, code: int) -> bool:
        if servo_id == BROADCAST_ID:
            return False
        return self.status_return_level(servo_id) >= _NEEDS_LEVEL.get(code, 3)

    def _level_written(self, address: int, data: bytes) -> int | None:
        """The Status Return Level a WRITE of ``data`` at ``address`` sets, if it sets one."""
        where = self._level_address
        if where is None or not address <= where < address + len(data):
            return None
        return data[where - address]

    def _after_write(self, servo_id: int, address: int, data: bytes) -> None:
        level = self._level_written(address, data)
        if level is not None and level <= 2:
            self.set_status_return_level(servo_id, level)

    # -- transactions ---------------------------------------------------------------------

    def send(self, packet: bytes) -> None:
        """Put an instruction on the bus and wait for no reply (broadcast, SYNC_WRITE, or a
        servo whose Status Return Level says it will not answer)."""
        packet = bytes(packet)
        with self._lock:
            self._port.reset_input_buffer()
            self._port.write(packet)
            self._recent.append(packet)

    def transact(
        self,
        packet: bytes,
        expect_id: int,
        expect_params_len: int,
        *,
        check: bool = True,
        retries: int | None = None,
        silence_s: float | None = None,
    ) -> Packet:
        """Send ``packet`` and return the status packet from ``expect_id`` carrying
        ``expect_params_len`` parameter bytes.

        Retries timed-out or corrupt replies (``retries`` overrides the client's count)
        and then raises :class:`DxlTimeout` or :class:`CorruptPacket`. A reply with error
        bits raises :class:`ServoError` at once unless ``check`` is False.

        ``silence_s``: end an attempt this long after the write if nothing but the
        instruction's echo has been heard (a scan, where most IDs never answer: by then
        the first byte of any reply has arrived); once something is heard, the whole
        reply timeout applies.
        """
        packet = bytes(packet)
        if len(packet) < 6 or packet[:2] != b"\xff\xff":
            raise PacketArgumentError(f"not an instruction packet: {packet.hex(' ')}")
        tries = self._tries(retries)
        return self._transact(packet, expect_id, expect_params_len, check, tries, silence_s)

    def _tries(self, retries: int | None) -> int:
        """Attempts for a transaction: the client's retries, or ``retries`` if given."""
        return 1 + (self.retries if retries is None else settings.resolve_retries(retries))

    def _transact(
        self,
        packet: bytes,
        expect_id: int,
        expect_len: int,
        check: bool,
        tries: int,
        silence_s: float | None = None,
        sent: tuple[float, bytes] | None = None,
    ) -> Packet:
        """:meth:`transact` of an instruction packet known to be well formed. ``sent``:
        the first attempt's instruction is already written, at that time, and that is
        what its first read returned (the caller holds the lock)."""
        timeout = self._reply_timeout(len(packet), expect_len)
        attempts: list[_Attempt] = []
        with self._lock:
            for _ in range(tries):
                reply, attempt = self._attempt(
                    packet, expect_id, expect_len, timeout, silence_s, sent
                )
                sent = None
                if reply is None and self._echo is None and attempt.echo is not None:
                    reply = self._settle_echo(attempt.echo, expect_id, expect_len)
                if reply is not None:
                    if reply.code & _RESEND_MASK and len(attempts) + 1 < tries:
                        attempts.append(attempt)  # the servo heard a damaged instruction
                        continue
                    if check and reply.code:
                        raise ServoError(reply.id, reply.code)
                    return reply
                attempts.append(attempt)
        raise self._failure(packet, expect_id, expect_len, timeout, attempts)

    def _reply_timeout(self, tx_len: int, params_len: int) -> float:
        """``self.timing.reply_timeout_s``, remembered per packet shape."""
        key = (tx_len, params_len)
        timeout = self._timeouts.get(key)
        if timeout is None:
            timeout = self._timeouts[key] = self._timing.reply_timeout_s(tx_len, params_len)
        return timeout

    def _attempt(
        self,
        packet: bytes,
        expect_id: int,
        expect_len: int,
        timeout: float,
        silence_s: float | None = None,
        sent: tuple[float, bytes] | None = None,
    ) -> tuple[Packet | None, _Attempt]:
        parser = self._parser
        seen = _CLEAN  # replaced by an _Attempt of its own once anything else is heard
        echo = self._echo
        io = self._io
        parser.reset()
        if sent is None:
            io.flush_input()
            io.write(packet)
            start, data = time.monotonic(), b""
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
            if data and seen is _CLEAN:
                seen = _Attempt()
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
                    seen.wrong_shape.append(event)
                    continue
                if echo is None:
                    self._echo = seen.echo_seen
                self._recent.append(packet)
                return event, seen
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                self._recent.append(packet)
                return None, _Attempt() if seen is _CLEAN else seen
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
                reply = _exact_reply(data, expect_id, expect_len)
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
        deadline = time.monotonic() + wait
        heard_probe = False
        while not heard_probe:
            remaining = deadline - time.monotonic()
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

    def _failure(
        self,
        packet: bytes,
        expect_id: int,
        expect_len: int,
        timeout: float,
        attempts: list[_Attempt],
    ) -> ProtocolError:
        """The error for a transaction whose every attempt failed: corrupt if any attempt
        heard a damaged or misshapen reply, else a timeout."""
        what = f"{_instruction_name(packet[4])} to servo {expect_id}"
        tries = len(attempts)
        tried = f"{tries} attempt{'s' if tries != 1 else ''}"
        last = attempts[-1]
        misshapen = [p for a in attempts for p in a.wrong_shape]
        damaged = [r for a in attempts for r in a.rejected]
        if misshapen:
            bad = misshapen[-1]
            flags = f" with error bits: {bad.error.describe()}" if bad.code else ""
            return CorruptPacket(
                f"servo {expect_id} answered {what} with {len(bad.params)} data bytes where "
                f"{expect_len} were expected{flags} ({tried}): check that only one device "
                "has this ID and that the address and length are valid for it"
            )
        if damaged:
            hit = sum(1 for a in attempts if a.rejected)
            return CorruptPacket(
                f"corrupt reply to {what} at {self.baudrate} baud (damaged packets in {hit} "
                f"of {tried}, e.g. {damaged[-1].data.hex(' ')}): check the cable and "
                "connectors, that every device on the bus uses this baud rate, and that no "
                "two share an ID"
            )
        if self._echo is None and last.echo_seen:
            echo_hint = (
                "; the only packet heard was identical to the instruction, which auto echo "
                "detection took for an echo: if this bus does not echo, pass echo=False "
                "(SNAKEBOT_ECHO=off)"
            )
        elif self._echo is True and not last.echo_seen:
            echo_hint = (
                "; the instruction's echo was not heard either: if this adapter does not "
                "echo, pass echo=False (SNAKEBOT_ECHO=off)"
            )
        else:
            echo_hint = ""
        timeout_error = DxlTimeout(
            f"no reply to {what} within {timeout * 1e3:.1f} ms at {self.baudrate} baud "
            f"({tried}). Check that the servos are powered (USB does not power them), that "
            f"the baud rate matches the servo's (AX-12 factory setting: 1000000), that a "
            f"servo with ID {expect_id} is on the bus (scan for it), and, on a slow USB "
            f"adapter, raise SNAKEBOT_LATENCY_MS{echo_hint}"
        )
        timeout_error.echo_missing = self._echo is True and not last.echo_seen
        return timeout_error

    def _exchange(self, packet: bytes, servo_id: int, expect_len: int) -> Packet | None:
        """Transact if ``servo_id`` will answer this instruction, else just send."""
        if self._answers(servo_id, packet[4]):
            return self.transact(packet, servo_id, expect_len)
        self.send(packet)
        return None

    # -- instructions ---------------------------------------------------------------------

    def ping(
        self,
        servo_id: int,
        *,
        check: bool = True,
        retries: int | None = None,
        silence_s: float | None = None,
    ) -> Packet:
        """PING ``servo_id`` and return its status packet (``.error`` holds its flags).

        With ``check=False`` a servo in alarm is reported, not raised; ``retries=0`` and
        ``silence_s`` (:meth:`transact`) suit a bus scan, where most IDs are silent.
        """
        _require_device(servo_id, "PING")
        tries = self._tries(retries)
        return self._transact(_ping_packet(servo_id), servo_id, 0, check, tries, silence_s)

    def read(self, servo_id: int, address: int, length: int) -> bytes:
        """READ ``length`` bytes of ``servo_id``'s control table from ``address``."""
        plan = self._read_plans.get((servo_id, address, length))
        if plan is None:
            plan = self._read_plan(servo_id, address, length)
        if self._levels.get(servo_id, self._default_level) < 1:  # status_return_level
            raise PacketArgumentError(
                f"servo {servo_id} is set to Status Return Level 0, so it never answers "
                "READ: write 1 or 2 to its Status Return Level, then call "
                "set_status_return_level"
            )
        checks = plan.checks
        for _ in range(1 + self.retries):
            data = self._read_once(plan)
            if not checks:
                return data
            wrong = _violation(checks, data)
            if wrong is None:
                return data
        raise CorruptPacket(
            f"servo {servo_id} returned {wrong} in each of {1 + self.retries} READs: a damaged "
            "reply the checksum let through, or a servo that is not the model expected; check "
            "the cable and the servo's model number"
        )

    def _read_plan(self, servo_id: int, address: int, length: int) -> _ReadPlan:
        """What every READ of ``length`` bytes at ``address`` of ``servo_id`` needs, made
        once (and kept, up to :data:`READ_PLANS` of them)."""
        _require_device(servo_id, "READ")
        packet = protocol.read(servo_id, address, length)
        reply = protocol.status(servo_id, 0, bytes(length))  # the shape of a clean answer
        plan = _ReadPlan(
            packet=packet,
            servo_id=servo_id,
            length=length,
            timeout=self._reply_timeout(len(packet), length),
            reply_len=len(reply),
            head=reply[: len(reply) - length - 1],
            checks=self._checks_within(address, length),
        )
        plans = self._read_plans
        if len(plans) >= READ_PLANS:
            plans.clear()
        plans[servo_id, address, length] = plan
        return plan

    def _read_once(self, plan: _ReadPlan) -> bytes:
        """One READ transaction (with its retries): the data read. Once the client knows
        whether the bus echoes, the first read asks for exactly the echo (if any) and the
        reply; if that is what arrives, whole and clean, it is checked with a comparison
        or two and a sum and returned at once. Anything else goes on in :meth:`_attempt`
        (the same attempt, so the same outcome as if it had started there)."""
        packet = plan.packet
        with self._lock:
            sent = None
            echo = self._echo
            if echo is not None:
                skip = len(packet) if echo else 0  # the echo comes first, whole
                start = time.monotonic()
                data = self._io.exchange(packet, skip + plan.reply_len, plan.timeout)
                if (
                    len(data) == skip + plan.reply_len
                    and data.startswith(plan.head, skip)
                    and sum(data[skip:]) & 0xFF == _INTACT_SUM
                    # with an echo: first exactly ours, then a reply that is not the late
                    # echo of an earlier instruction (which _attempt would skip)
                    and (not echo or (data.startswith(packet) and data[skip:] not in self._recent))
                ):
                    self._recent.append(packet)
                    return data[skip + len(plan.head) : -1]
                sent = (start, data)
            tries = 1 + self.retries
            reply = self._transact(packet, plan.servo_id, plan.length, True, tries, None, sent)
            return reply.params

    def read_confirmed(self, servo_id: int, address: int, length: int) -> bytes:
        """READ until two replies in a row agree, and return that value: for reads that
        decisions are based on (a servo's model, a value written and read back), where a
        damaged reply that the checksum let through must not count. CorruptPacket if no
        two agree within the retries."""
        last = self.read(servo_id, address, length)
        for _ in range(1 + self.retries):
            data = self.read(servo_id, address, length)
            if data == last:
                return data
            last = data
        raise CorruptPacket(
            f"servo {servo_id} gave {2 + self.retries} different values for {length} bytes at "
            f"address {address}: check the cable, and that the value is not changing"
        )

    def _out_of_range(self, address: int, data: bytes) -> str | None:
        """What in ``data`` (read from ``address``) lies outside its register's range, in
        words, or None."""
        return _violation(self._checks_within(address, len(data)), data)

    def _checks_within(self, address: int, length: int) -> list[_RangeCheck]:
        """:meth:`_ranges_within`, remembered per (address, length)."""
        key = (address, length)
        checks = self._range_checks.get(key)
        if checks is None:
            checks = self._range_checks[key] = self._ranges_within(address, length)
        return checks

    def _ranges_within(self, address: int, length: int) -> list[_RangeCheck]:
        """(name, offset, size, signed, low, high) of each readable register of the device
        with a known range (Register.read_range) that lies wholly within ``length`` bytes
        from ``address``."""
        if not self.check_ranges:
            return []
        spans = [
            (r, r.read_range())
            for r in self.device.registers
            if r.readable and address <= r.address and r.end <= address + length
        ]
        return [
            (r.name, r.address - address, r.size, r.signed, *span)
            for r, span in spans
            if span is not None
        ]

    def read_u8(self, servo_id: int, address: int) -> int:
        """READ one byte."""
        return self.read(servo_id, address, 1)[0]

    def read_u16(self, servo_id: int, address: int) -> int:
        """READ a 2-byte little-endian word (e.g. Present Position at 36)."""
        return int.from_bytes(self.read(servo_id, address, 2), "little")

    def model_number(self, servo_id: int) -> int:
        """The servo's model number (12 for an AX-12A, 300 for an AX-12W)."""
        return self.read_u16(servo_id, self.device.register("Model Number").address)

    def write(self, servo_id: int, address: int, data: bytes) -> None:
        """WRITE ``data`` at ``address`` (waits for the status if the servo sends one)."""
        data = bytes(data)
        packet = protocol.write(servo_id, address, data)
        wait = self._answers(servo_id, Instruction.WRITE)
        level = self._level_written(address, data)
        if level is not None:
            # Whether this very write is answered depends on the level before and after.
            wait = wait and level >= 2
        if wait:
            self._transact_write(packet, servo_id, address, data)
        else:
            self.send(packet)
        self._after_write(servo_id, address, data)

    def _transact_write(self, packet: bytes, servo_id: int, address: int, data: bytes) -> None:
        """A WRITE that waits for its status. A RANGE error for data that the register
        description says is in range means the servo heard other data (damage the
        checksum let through), so the WRITE is sent again, like after a damaged reply."""
        in_range = bool(self._ranges_within(address, len(data))) and (
            self._out_of_range(address, data) is None
        )
        for attempt in range(1 + self.retries):
            try:
                self.transact(packet, servo_id, 0)
                return
            except ServoError as exc:
                damaged = in_range and exc.flags & ErrorFlags.RANGE
                if not damaged or attempt == self.retries:
                    raise

    def write_u8(self, servo_id: int, address: int, value: int) -> None:
        """WRITE one byte."""
        self.write(servo_id, address, _encode_uint(value, 1))

    def write_u16(self, servo_id: int, address: int, value: int) -> None:
        """WRITE a 2-byte little-endian word (e.g. Goal Position at 30)."""
        self.write(servo_id, address, _encode_uint(value, 2))

    def reg_write(self, servo_id: int, address: int, data: bytes) -> None:
        """REG_WRITE: stage ``data`` at ``address`` until :meth:`action`."""
        self._exchange(protocol.reg_write(servo_id, address, bytes(data)), servo_id, 0)

    def action(self, servo_id: int = BROADCAST_ID) -> None:
        """ACTION: apply staged REG_WRITEs (broadcast by default, so no reply)."""
        self._exchange(protocol.action(servo_id), servo_id, 0)

    def reset(self, servo_id: int) -> None:
        """RESET ``servo_id`` to factory defaults (ID 1, 1 Mbps, Status Return Level 2)."""
        _require_device(servo_id, "RESET")
        self._exchange(protocol.reset(servo_id), servo_id, 0)
        self._levels.pop(servo_id, None)
        self._levels[1] = DEFAULT_STATUS_RETURN_LEVEL

    def sync_write(self, address: int, length: int, data: Mapping[int, bytes]) -> None:
        """SYNC_WRITE ``length`` bytes at ``address`` to each servo in ``data`` (no reply)."""
        self.send(protocol.sync_write(address, length, data))
        for servo_id, chunk in data.items():
            self._after_write(servo_id, address, bytes(chunk))


@functools.lru_cache(maxsize=256)
def _ping_packet(servo_id: int) -> bytes:
    """``protocol.ping``, built once per ID: a scan sends one to every ID, again and again."""
    return protocol.ping(servo_id)


def _violation(checks: list[_RangeCheck], data: bytes) -> str | None:
    """The first value in ``data`` outside its register's range (``checks``), in words."""
    for name, offset, size, signed, low, high in checks:
        value = int.from_bytes(data[offset : offset + size], "little", signed=signed)
        if not low <= value <= high:
            return f"{name} = {value}, outside its range {low}..{high}"
    return None


def _exact_reply(data: bytes, expect_id: int, expect_len: int) -> Packet | None:
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


def _require_device(servo_id: int, what: str) -> None:
    if servo_id == BROADCAST_ID:
        raise PacketArgumentError(
            f"{what} cannot go to the broadcast ID {BROADCAST_ID}: no servo answers a "
            "broadcast; address one servo ID (0-253)"
        )


def _check_level(level: int) -> int:
    if level not in (0, 1, 2):
        raise ValueError(f"Status Return Level must be 0, 1 or 2, got {level!r}")
    return level


def _encode_uint(value: int, size: int) -> bytes:
    if not isinstance(value, int) or not 0 <= value < 1 << (8 * size):
        raise ValueError(f"value must be an integer 0..{(1 << (8 * size)) - 1}, got {value!r}")
    return value.to_bytes(size, "little")
