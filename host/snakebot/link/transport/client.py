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

The client is one class made of parts, each in its own module of
``snakebot.link.transport`` and all working on the same attributes (``client_state``):
Status Return Levels (``levels``), transactions and retries (``transaction``), reading a
reply and telling echoes and stale replies from it (``reply``), READs (``reads``) and
writes (``writes``); the timing terms are ``timing``'s. This module ties them together,
with the port.
"""

from __future__ import annotations

import threading
from collections import deque
from types import TracebackType

import serial

from snakebot.facts import devices
from snakebot.facts.devices import Device
from snakebot.formats.protocol import PacketParser
from snakebot.link.transport import settings
from snakebot.link.transport.levels import DEFAULT_STATUS_RETURN_LEVEL, StatusLevels, check_level
from snakebot.link.transport.portio import PortIO
from snakebot.link.transport.ports import open_port
from snakebot.link.transport.reads import READ_PLANS, Reads
from snakebot.link.transport.reply import RECENT_SENDS, ReplyReader
from snakebot.link.transport.settings import EchoSetting
from snakebot.link.transport.timing import DEFAULT_BAUDRATE, BusTiming
from snakebot.link.transport.transaction import RESEND_FLAGS, Transactions
from snakebot.link.transport.writes import Writes

__all__ = [
    "DEFAULT_STATUS_RETURN_LEVEL",
    "READ_PLANS",
    "RECENT_SENDS",
    "RESEND_FLAGS",
    "DxlClient",
]


class DxlClient(Reads, Writes, Transactions, ReplyReader, StatusLevels):
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
        self._default_level = check_level(status_return_level)
        self._levels = {}
        self.device = device or devices.ax12()
        self._level_address = self.device.status_return_level_address
        self.check_ranges = check_ranges
        self._range_checks = {}
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
        self._echo = None if echo_setting == "auto" else bool(echo_setting)
        self._parser = PacketParser()
        self._recent = deque(maxlen=RECENT_SENDS)
        self._read_timeout = None
        self._lock = threading.RLock()

    @property
    def timing(self) -> BusTiming:
        """The bus's timing terms; assigning new ones applies them to every later
        transaction."""
        return self._timing

    @timing.setter
    def timing(self, timing: BusTiming) -> None:
        self._timing = timing
        # both hold timeouts computed from the timing
        self._timeouts = {}
        self._read_plans = {}

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
