"""The independent watchdog (RM0008 section 19).

Key register: 0xCCCC starts it (and the LSI), 0xAAAA reloads the counter from RLR,
0x5555 opens PR and RLR for writing until any other key. An update of PR or RLR shows in
SR (PVU, RVU) for about five LSI cycles. Once started it cannot be stopped; the counter
runs down at LSI / (4 << PR) and reaching 0 resets the chip. The LSI is an RC oscillator
of 30 to 60 kHz (40 kHz nominal): ``lsi_hz`` picks one, so a test can check the firmware
with the fastest one. Every reload is recorded (:attr:`Iwdg.largest_gap`) for the check
that the watchdog never starves.
"""

from __future__ import annotations

from collections.abc import Callable

from snakebot.core import ffi, lib
from snakebot.sim.mcu.regs import Clock, Peripheral
from snakebot.sim.mcu.schedule import Event, Scheduler

BASE = 0x40003000
KR, PR, RLR, SR = 0x0, 0x4, 0x8, 0xC
KEY_RELOAD, KEY_ACCESS, KEY_START = 0xAAAA, 0x5555, 0xCCCC
PVU, RVU = 1 << 0, 1 << 1
LSI_NOMINAL_HZ = 40_000
UPDATE_CYCLES = 5


class Iwdg(Peripheral):
    """``on_timeout()`` resets the chip."""

    name = "IWDG"

    def __init__(
        self,
        scheduler: Scheduler,
        now: Clock,
        *,
        on_timeout: Callable[[], None],
        lsi_hz: float = LSI_NOMINAL_HZ,
        strict: bool = True,
    ) -> None:
        super().__init__(BASE, strict=strict)
        self.scheduler = scheduler
        self.now = now
        self.on_timeout = on_timeout
        self.lsi_hz = lsi_hz
        self._timeout: Event | None = None
        self.fast = ffi.new("mcu_fast_io *")  # reloads noted in C (see mcu_count.h)
        self.fast.kind = lib.MCU_IO_IWDG_KR
        self.reset()

    def reset(self) -> None:
        if self._timeout is not None:
            self._timeout.cancel()
        self._timeout = None
        self.pr = 0
        self.rlr = 0xFFF
        self.sr = 0
        self._access = False
        fast = self.fast
        fast.running = 0
        fast.feeds = 0
        fast.last_feed = 0.0
        fast.largest_gap = 0.0

    @property
    def running(self) -> bool:
        return bool(self.fast.running)

    @property
    def feeds(self) -> int:
        return int(self.fast.feeds)

    @property
    def last_feed(self) -> float | None:
        return float(self.fast.last_feed) if self.fast.feeds else None

    @property
    def largest_gap(self) -> float:
        """The longest time between two reloads so far (seconds)."""
        return float(self.fast.largest_gap)

    def timeout_s(self) -> float:
        """How long from a reload to a reset, at :attr:`lsi_hz`."""
        return (self.rlr + 1) * (4 << min(self.pr, 6)) / self.lsi_hz

    def _reload(self) -> None:
        # A reload only notes the time (the firmware feeds on every pass of its loop): the
        # one timeout event, when it comes due, looks whether a feed has moved it on.
        now = self.now()
        fast = self.fast
        if fast.feeds and now - fast.last_feed > fast.largest_gap:
            fast.largest_gap = now - fast.last_feed
        fast.last_feed = now
        fast.feeds += 1
        if self._timeout is None:
            self._timeout = self.scheduler.at(now + self.timeout_s(), self._expired)

    def _expired(self, t: float) -> None:
        self._timeout = None
        assert self.last_feed is not None
        deadline = self.last_feed + self.timeout_s()
        if deadline > t + 1e-12:
            self._timeout = self.scheduler.at(deadline, self._expired)
            return
        self.on_timeout()

    def _updating(self, flag: int) -> None:
        self.sr |= flag

        def done(_t: float) -> None:
            self.sr &= ~flag

        self.scheduler.at(self.now() + UPDATE_CYCLES / self.lsi_hz, done)

    def read(self, offset: int, size: int) -> int:
        if not self.word_only(offset, size, None):
            return 0
        if offset == KR:
            return 0
        if offset == PR:
            return self.pr
        if offset == RLR:
            return self.rlr
        if offset == SR:
            return self.sr
        return self.unknown(offset, size, None)

    def write(self, offset: int, size: int, value: int) -> None:
        if not self.word_only(offset, size, value):
            return
        if offset == KR:
            key = value & 0xFFFF
            self._access = key == KEY_ACCESS
            if key == KEY_START:
                self.fast.running = 1
                self._reload()
            elif key == KEY_RELOAD and self.running:
                self._reload()
        elif offset in (PR, RLR):
            if not self._access:
                return  # write-protected
            if offset == PR:
                self.pr = value & 7
                self._updating(PVU)
            else:
                self.rlr = value & 0xFFF
                self._updating(RVU)
        elif offset == SR:
            return  # read-only
        else:
            self.unknown(offset, size, value)
