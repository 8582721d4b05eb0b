"""READs: each (servo, address, length) planned once (packet, timeout, the clean reply's
head, range checks), the usual clean reply taken in one exchange on the port and
checked with a sum, values checked against their registers' ranges and read again when
outside, and READs confirmed by two agreeing replies."""

from __future__ import annotations

from dataclasses import dataclass

from snakebot.formats import protocol
from snakebot.formats.protocol import CorruptPacket, PacketArgumentError
from snakebot.formats.protocol.instructions import HEADER
from snakebot.link.transport.client_state import ClientState
from snakebot.link.transport.transaction import require_device

READ_PLANS = 4096
"""How many (servo, address, length) READs a client keeps ready-made (packet, timeout,
expected reply header, range checks); more are made again as needed."""

_INTACT_SUM = (sum(HEADER) + 0xFF) & 0xFF
"""The low byte of the sum of every byte of an intact packet: the header's, plus ID to
CHECKSUM, which the checksum makes 0xFF (mod 256). One sum checks a whole reply."""

RangeCheck = tuple[str, int, int, bool, int, int]
"""(register name, offset in the data read, size, signed, lowest, highest)."""


@dataclass(frozen=True, slots=True)
class ReadPlan:
    """Everything a READ of one (servo, address, length) needs, made once: a control
    loop reads the same registers of the same servos over and over."""

    packet: bytes  # the instruction
    servo_id: int
    length: int
    timeout: float  # the reply timeout for this instruction and reply
    reply_len: int  # the whole status packet
    head: bytes  # a clean reply's bytes before its data: header, ID, LEN, no error bits
    checks: list[RangeCheck]  # the registers with a range within the bytes read


def violation(checks: list[RangeCheck], data: bytes) -> str | None:
    """The first value in ``data`` outside its register's range (``checks``), in words."""
    for name, offset, size, signed, low, high in checks:
        value = int.from_bytes(data[offset : offset + size], "little", signed=signed)
        if not low <= value <= high:
            return f"{name} = {value}, outside its range {low}..{high}"
    return None


class Reads(ClientState):
    """READ transactions and their checks (a part of
    :class:`~snakebot.link.transport.client.DxlClient`)."""

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
            wrong = violation(checks, data)
            if wrong is None:
                return data
        raise CorruptPacket(
            f"servo {servo_id} returned {wrong} in each of {1 + self.retries} READs: a damaged "
            "reply the checksum let through, or a servo that is not the model expected; check "
            "the cable and the servo's model number"
        )

    def _read_plan(self, servo_id: int, address: int, length: int) -> ReadPlan:
        """What every READ of ``length`` bytes at ``address`` of ``servo_id`` needs, made
        once (and kept, up to :data:`READ_PLANS` of them)."""
        require_device(servo_id, "READ")
        packet = protocol.read(servo_id, address, length)
        reply = protocol.status(servo_id, 0, bytes(length))  # the shape of a clean answer
        plan = ReadPlan(
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

    def _read_once(self, plan: ReadPlan) -> bytes:
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
                start = self._io.clock()
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
        return violation(self._checks_within(address, len(data)), data)

    def _checks_within(self, address: int, length: int) -> list[RangeCheck]:
        """:meth:`_ranges_within`, remembered per (address, length)."""
        key = (address, length)
        checks = self._range_checks.get(key)
        if checks is None:
            checks = self._range_checks[key] = self._ranges_within(address, length)
        return checks

    def _ranges_within(self, address: int, length: int) -> list[RangeCheck]:
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
