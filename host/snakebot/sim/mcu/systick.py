"""SysTick, the Cortex-M3's 24-bit down-counter (ARMv7-M architecture manual, B3.3).

The counter runs on the processor clock (CLKSOURCE = 1) or, on the STM32, HCLK / 8
(CLKSOURCE = 0). Enabled, it counts down from its value; on the step from 1 to 0 it sets
COUNTFLAG and, with TICKINT, pends the SysTick exception; the step after 0 reloads RVR.
A write to CVR clears it (and COUNTFLAG) without an exception; reading CSR clears
COUNTFLAG. The counter's value is worked out from the time, so it is exact at every read.
CALIB reads as the STM32's value (9000 counts of HCLK/8 in 1 ms at 72 MHz).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from snakebot.sim.mcu.regs import Clock, Peripheral
from snakebot.sim.mcu.schedule import Event, Scheduler

BASE = 0xE000E010
CSR, RVR, CVR, CALIB = 0x0, 0x4, 0x8, 0xC
ENABLE, TICKINT, CLKSOURCE, COUNTFLAG = 1 << 0, 1 << 1, 1 << 2, 1 << 16
CALIB_VALUE = 9000
MAX = 0x00FF_FFFF


class SysTick(Peripheral):
    """``pend()`` pends the SysTick exception; :meth:`set_hclk` tells the processor clock."""

    name = "SysTick"
    size = 0x10

    def __init__(
        self,
        scheduler: Scheduler,
        now: Clock,
        *,
        pend: Callable[[], None],
        hclk_hz: int = 8_000_000,
        strict: bool = True,
    ) -> None:
        super().__init__(BASE, strict=strict)
        self.scheduler = scheduler
        self.now = now
        self.pend = pend
        self.hclk_hz = hclk_hz
        self._zero: Event | None = None
        self.fired = 0
        self.reset()

    def reset(self) -> None:
        if self._zero is not None:
            self._zero.cancel()
        self._zero = None
        self.csr = 0
        self.rvr = 0
        self._value = 0  # the counter when stopped, or at _anchor while it runs
        self._anchor = 0.0

    def tick_s(self) -> float:
        hz = self.hclk_hz if self.csr & CLKSOURCE else self.hclk_hz / 8
        return 1.0 / hz

    def value(self) -> int:
        """The counter now."""
        if not self.csr & ENABLE:
            return self._value
        steps = math.floor((self.now() - self._anchor) / self.tick_s() + 1e-6)
        if steps <= self._value:
            return self._value - steps
        if self.rvr == 0:
            return 0
        return self.rvr - (steps - self._value - 1) % (self.rvr + 1)

    def _freeze(self) -> None:
        """Take the running count as the new starting point."""
        if self.csr & ENABLE:
            self._value = self.value()
        self._anchor = self.now()

    def _rearm(self) -> None:
        if self._zero is not None:
            self._zero.cancel()
            self._zero = None
        if not self.csr & ENABLE:
            return
        if self._value:
            steps = self._value
        elif self.rvr:
            steps = self.rvr + 1
        else:
            return  # RVR 0: the counter stays at 0, no exception
        self._zero = self.scheduler.at(self._anchor + steps * self.tick_s(), self._reached_zero)

    def _reached_zero(self, t: float) -> None:
        self._zero = None
        self.fired += 1
        self.csr |= COUNTFLAG
        if self.csr & TICKINT:
            self.pend()
        self._anchor = t
        self._value = 0
        self._rearm()

    def set_hclk(self, hz: int) -> None:
        """The processor clock changes now: the count so far stands, the rest runs at
        the new rate."""
        if hz == self.hclk_hz:
            return
        self._freeze()
        self.hclk_hz = hz
        self._rearm()

    def read(self, offset: int, size: int) -> int:
        if not self.word_only(offset, size, None):
            return 0
        if offset == CSR:
            value = self.csr
            self.csr &= ~COUNTFLAG
            return value
        if offset == RVR:
            return self.rvr
        if offset == CVR:
            return self.value()
        if offset == CALIB:
            return CALIB_VALUE
        return self.unknown(offset, size, None)

    def write(self, offset: int, size: int, value: int) -> None:
        if not self.word_only(offset, size, value):
            return
        if offset == CSR:
            self._freeze()
            self.csr = (self.csr & COUNTFLAG) | (value & (ENABLE | TICKINT | CLKSOURCE))
        elif offset == RVR:
            self._freeze()
            self.rvr = value & MAX
        elif offset == CVR:
            self._anchor = self.now()
            self._value = 0
            self.csr &= ~COUNTFLAG
        else:
            self.unknown(offset, size, value)
            return
        self._rearm()
