"""SysTick, the Cortex-M3's 24-bit down-counter (ARMv7-M architecture manual, B3.3).

The counter runs on the processor clock (CLKSOURCE = 1) or, on the STM32, HCLK / 8
(CLKSOURCE = 0). Enabled, it counts down from its value; on the step from 1 to 0 it sets
COUNTFLAG and, with TICKINT, pends the SysTick exception; the step after 0 reloads RVR.
A write to CVR clears it (and COUNTFLAG) without an exception; reading CSR clears
COUNTFLAG. The counter's value is worked out from the time, so it is exact at every read.
CALIB reads as the STM32's value (9000 counts of HCLK/8 in 1 ms at 72 MHz).

The state lives in ``c`` (an ``mcu_systick``, mcu_systick.h), where the formulas are: on
the chip the CPU's CSR and CVR reads are served there, and once the machine times it
there (:meth:`SysTick.time_in_c`) the step to zero runs there too, at the instruction a
scheduled event would run at; otherwise this model schedules it.
"""

from __future__ import annotations

from collections.abc import Callable

from snakebot.core import ffi, lib
from snakebot.sim.mcu.regs import Clock, Peripheral, kept_in
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
        self.c = ffi.new("mcu_systick *")
        self.c.hclk_hz = hclk_hz
        self._counter: object = None  # the machine's mcu_counter once timed in C
        self._zero: Event | None = None
        self.reset()

    def reset(self) -> None:
        if self._zero is not None:
            self._zero.cancel()
        self._zero = None
        self.c.armed = 0
        self.csr = 0
        self.rvr = 0
        self._value = 0  # the counter when stopped, or at _anchor while it runs
        self._anchor = 0.0
        if self._counter is not None:
            lib.mcu_timed_plan(self._counter)

    # -- the state, kept in ``c`` ---------------------------------------------------------

    csr = kept_in("c", "csr")
    rvr = kept_in("c", "rvr")
    _value = kept_in("c", "value")
    _anchor = kept_in("c", "anchor")
    hclk_hz = kept_in("c", "hclk_hz")

    @property
    def fired(self) -> int:
        """Steps to zero so far."""
        return int(self.c.fired)

    def time_in_c(self, counter: object, nvic: object, exception: int) -> None:
        """Let the machine's instruction counter ``counter`` time the step to zero, in C,
        pending ``exception`` in the C NVIC ``nvic`` (None: this model times it)."""
        self._counter = counter
        self.c.nvic = ffi.NULL if counter is None else nvic
        self.c.exception = exception
        if counter is not None:
            counter.systick = self.c
        self._rearm()

    def tick_s(self) -> float:
        return float(lib.mcu_systick_tick_s(self.c))

    def value(self) -> int:
        """The counter now."""
        return int(lib.mcu_systick_value(self.c, self.now()))

    def _freeze(self) -> None:
        """Take the running count as the new starting point."""
        if self.csr & ENABLE:
            self._value = self.value()
        self._anchor = self.now()

    def _rearm(self) -> None:
        if self._zero is not None:
            self._zero.cancel()
            self._zero = None
        c = self.c
        lib.mcu_systick_rearm(c)
        if self._counter is not None:
            lib.mcu_timed_plan(self._counter)
        elif c.armed:
            self._zero = self.scheduler.at(c.zero_at, self._reached_zero)

    def _reached_zero(self, t: float) -> None:
        self._zero = None
        tickint = self.csr & TICKINT
        lib.mcu_systick_zero(self.c)  # COUNTFLAG, reload (no NVIC here: no pend)
        if tickint:
            self.pend()
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
