"""Transactions: an instruction out and the awaited status packet back, with retries
for timed-out and damaged replies and for replies saying the servo heard a damaged
instruction, the reply timeout from the wire's timing, the error that says what went
wrong when every attempt failed, and PING."""

from __future__ import annotations

import functools

from snakebot.formats import protocol
from snakebot.formats.protocol import (
    BROADCAST_ID,
    CorruptPacket,
    DxlTimeout,
    ErrorFlags,
    Instruction,
    Packet,
    PacketArgumentError,
    ProtocolError,
    ServoError,
)
from snakebot.link.transport import settings
from snakebot.link.transport.client_state import ClientState
from snakebot.link.transport.reply import Attempt

RESEND_FLAGS = ErrorFlags.CHECKSUM | ErrorFlags.INSTRUCTION
"""Status error bits saying the servo did not act on the instruction because it arrived
damaged: the instruction is sent again, like after a damaged reply."""

_RESEND_MASK = int(RESEND_FLAGS)  # a plain int: IntFlag's & costs a Python call per reply


@functools.cache
def instruction_name(code: int) -> str:
    try:
        return Instruction(code).name
    except ValueError:
        return f"instruction 0x{code:02X}"


@functools.lru_cache(maxsize=256)
def ping_packet(servo_id: int) -> bytes:
    """``protocol.ping``, built once per ID: a scan sends one to every ID, again and again."""
    return protocol.ping(servo_id)


def require_device(servo_id: int, what: str) -> None:
    if servo_id == BROADCAST_ID:
        raise PacketArgumentError(
            f"{what} cannot go to the broadcast ID {BROADCAST_ID}: no servo answers a "
            "broadcast; address one servo ID (0-253)"
        )


class Transactions(ClientState):
    """Instructions out, status packets back, retried (a part of
    :class:`~snakebot.link.transport.client.DxlClient`)."""

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
        attempts: list[Attempt] = []
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

    def _failure(
        self,
        packet: bytes,
        expect_id: int,
        expect_len: int,
        timeout: float,
        attempts: list[Attempt],
    ) -> ProtocolError:
        """The error for a transaction whose every attempt failed: corrupt if any attempt
        heard a damaged or misshapen reply, else a timeout."""
        what = f"{instruction_name(packet[4])} to servo {expect_id}"
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
        require_device(servo_id, "PING")
        tries = self._tries(retries)
        return self._transact(ping_packet(servo_id), servo_id, 0, check, tries, silence_s)
