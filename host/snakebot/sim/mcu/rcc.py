"""Reset and clock control (RM0008 section 7.3) as far as the firmware uses it.

Modelled: the HSI, HSE and PLL with their ready bits (each becomes ready a start-up time
after it is switched on, and not ready at once when switched off), the system clock switch
(SWS follows SW only to a source that is ready), the AHB and APB prescalers, the peripheral
clock enables, and the reset flags in CSR. The rules the hardware enforces are kept: the
PLL's source and multiplier cannot be written while the PLL is on, the PLL cannot be
stopped while it drives SYSCLK, nor the HSE while it drives SYSCLK directly or through the
PLL. Clock security, the LSE/LSI and CIR's interrupts are not modelled (CIR reads as
zero and takes writes of zero, which is all a firmware that uses none of them does).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from snakebot.sim.mcu.regs import Clock, Peripheral
from snakebot.sim.mcu.schedule import Event, Scheduler

BASE = 0x40021000

HSI_HZ = 8_000_000
HSI_STARTUP_S = 2e-6  # datasheet: 1 to 2 us
HSE_STARTUP_S = 2e-3  # datasheet: 2 ms for an 8 MHz crystal
PLL_LOCK_S = 200e-6  # datasheet: at most 200 us

CR, CFGR, CIR, APB2RSTR, APB1RSTR, AHBENR, APB2ENR, APB1ENR, BDCR, CSR = range(0, 0x28, 4)

HSION, HSIRDY, HSEON, HSERDY, HSEBYP, PLLON, PLLRDY = (
    1 << 0,
    1 << 1,
    1 << 16,
    1 << 17,
    1 << 18,
    1 << 24,
    1 << 25,
)
CR_RESET = 0x0000_0083  # HSI on and ready, HSITRIM 16
CR_WRITABLE = HSION | HSEON | HSEBYP | PLLON | (0x1F << 3)  # + HSITRIM
PLL_CONFIG = (1 << 16) | (1 << 17) | (0xF << 18)  # PLLSRC, PLLXTPRE, PLLMUL
CFGR_WRITABLE = 0x3 | (0xF << 4) | (0x7 << 8) | (0x7 << 11) | (0x3 << 14) | PLL_CONFIG | (1 << 22)
CFGR_WRITABLE |= 0x7 << 24  # MCO
AHBENR_RESET = 0x14  # SRAM and FLITF clocks on during sleep
CSR_RMVF = 1 << 24
CSR_FLAGS = 0xFC00_0000  # PINRSTF .. LPWRRSTF
CSR_PIN, CSR_POR, CSR_SFT, CSR_IWDG = 1 << 26, 1 << 27, 1 << 28, 1 << 29

SW_HSI, SW_HSE, SW_PLL = 0, 1, 2
AHB_DIVIDERS = {8: 2, 9: 4, 10: 8, 11: 16, 12: 64, 13: 128, 14: 256, 15: 512}
APB_DIVIDERS = {4: 2, 5: 4, 6: 8, 7: 16}


@dataclass(frozen=True)
class Clocks:
    """The frequencies in effect (Hz)."""

    sysclk: int
    hclk: int
    pclk1: int
    pclk2: int


class Rcc(Peripheral):
    """The clock tree. ``hse_hz``: the board's crystal (0: none fitted, the HSE never
    becomes ready). ``on_change`` is called with the new :class:`Clocks` whenever a
    frequency changes, ``on_gate()`` whenever a peripheral clock enable is written."""

    name = "RCC"

    def __init__(
        self,
        scheduler: Scheduler,
        now: Clock,
        *,
        hse_hz: int,
        on_change: Callable[[Clocks], None] | None = None,
        strict: bool = True,
    ) -> None:
        super().__init__(BASE, strict=strict)
        self.scheduler = scheduler
        self.now = now
        self.hse_hz = hse_hz
        self.on_change = on_change
        self.on_gate: Callable[[], None] | None = None
        self.csr = CSR_POR | CSR_PIN  # a power-on reset
        self._pending: dict[int, Event] = {}
        self.reset()

    def reset(self) -> None:
        for event in getattr(self, "_pending", {}).values():
            event.cancel()
        self._pending = {}
        self.cr = CR_RESET
        self.cfgr = 0
        self.apb2enr = 0
        self.apb1enr = 0
        self.ahbenr = AHBENR_RESET
        self._notify()

    def note_reset(self, flag: int) -> None:
        """A reset happened, of the kind ``flag`` (CSR_PIN, CSR_SFT, CSR_IWDG, CSR_POR):
        the flags stay until software clears them (RMVF), as on the chip."""
        self.csr |= flag | (CSR_PIN if flag in (CSR_SFT, CSR_IWDG) else 0)

    def refresh(self) -> None:
        """Registers were set directly (a test, a bootloader's leftovers): tell the
        machine the clocks they give."""
        self._notify()

    # -- what the rest of the machine asks ------------------------------------------------

    @property
    def sysclk_source(self) -> int:
        return (self.cfgr >> 2) & 3

    def pll_hz(self) -> int:
        mul = min(((self.cfgr >> 18) & 0xF) + 2, 16)
        if self.cfgr & (1 << 16):
            src = self.hse_hz // 2 if self.cfgr & (1 << 17) else self.hse_hz
        else:
            src = HSI_HZ // 2
        return src * mul

    def clocks(self) -> Clocks:
        """The frequencies in effect now."""
        last = getattr(self, "_last", None)
        return last if last is not None else self._compute()

    def _compute(self) -> Clocks:
        source = self.sysclk_source
        sysclk = {SW_HSI: HSI_HZ, SW_HSE: self.hse_hz, SW_PLL: self.pll_hz()}[source]
        hclk = sysclk // AHB_DIVIDERS.get((self.cfgr >> 4) & 0xF, 1)
        pclk1 = hclk // APB_DIVIDERS.get((self.cfgr >> 8) & 7, 1)
        pclk2 = hclk // APB_DIVIDERS.get((self.cfgr >> 11) & 7, 1)
        return Clocks(sysclk, hclk, pclk1, pclk2)

    def enabled(self, bus: str, bit: int) -> bool:
        """Whether a peripheral's clock is on: ``bus`` "apb1" or "apb2", its enable bit."""
        reg = self.apb1enr if bus == "apb1" else self.apb2enr
        return bool(reg & (1 << bit))

    # -- registers ------------------------------------------------------------------------

    def read(self, offset: int, size: int) -> int:
        if not self.word_only(offset, size, None):
            return 0
        if offset == CR:
            return self.cr
        if offset == CFGR:
            return self.cfgr
        if offset == CIR:
            return 0
        if offset == APB2ENR:
            return self.apb2enr
        if offset == APB1ENR:
            return self.apb1enr
        if offset == AHBENR:
            return self.ahbenr
        if offset == CSR:
            return self.csr
        return self.unknown(offset, size, None)

    def write(self, offset: int, size: int, value: int) -> None:
        if not self.word_only(offset, size, value):
            return
        if offset == CR:
            self._write_cr(value)
        elif offset == CFGR:
            self._write_cfgr(value)
        elif offset == CIR:
            if value & 0x00FF_FF00:  # interrupt enables or clears: not modelled
                self.unknown(offset, size, value)
        elif offset in (APB2ENR, APB1ENR):
            if offset == APB2ENR:
                self.apb2enr = value & 0x0038_FFFD
            else:
                self.apb1enr = value & 0x3AFE_C9FF
            if self.on_gate is not None:
                self.on_gate()
        elif offset == AHBENR:
            self.ahbenr = value & 0x0000_0557
        elif offset == CSR:
            if value & CSR_RMVF:
                self.csr &= ~CSR_FLAGS
            if value & 1:  # LSION
                self.unknown(offset, size, value)
        else:
            self.unknown(offset, size, value)

    def _write_cr(self, value: int) -> None:
        old = self.cr
        new = (old & ~CR_WRITABLE) | (value & CR_WRITABLE)
        source = self.sysclk_source
        pll_from_hse = bool(self.cfgr & (1 << 16))
        # The hardware refuses to stop what drives SYSCLK.
        if source == SW_HSI or (source == SW_PLL and not pll_from_hse):
            new |= HSION
        if source == SW_PLL:
            new |= PLLON
        if source == SW_HSE or (source == SW_PLL and pll_from_hse):
            new |= HSEON
        if old & HSEON:  # HSEBYP is written only while the HSE is off
            new = (new & ~HSEBYP) | (old & HSEBYP)
        self.cr = new
        for on, ready, delay in (
            (HSION, HSIRDY, HSI_STARTUP_S),
            (HSEON, HSERDY, HSE_STARTUP_S),
            (PLLON, PLLRDY, PLL_LOCK_S),
        ):
            if new & on and not old & on:
                if on == HSEON and not self.hse_hz:
                    continue  # no crystal: never ready
                if on == PLLON and self.cfgr & (1 << 16) and not self.cr & HSERDY:
                    continue  # the PLL locks only once its source runs (_source_ready)
                self._later(ready, delay)
            elif old & on and not new & on:
                event = self._pending.pop(ready, None)
                if event is not None:
                    event.cancel()
                self.cr &= ~ready
                if on == HSEON and self.cfgr & (1 << 16):
                    self.cr &= ~PLLRDY  # its input gone, the PLL loses lock

    def _later(self, ready: int, delay: float) -> None:
        def become_ready(_t: float) -> None:
            self._pending.pop(ready, None)
            self.cr |= ready
            if ready == HSERDY and self.cr & PLLON and self.cfgr & (1 << 16):
                self._later(PLLRDY, PLL_LOCK_S)
            self._try_switch()

        self._pending[ready] = self.scheduler.at(self.now() + delay, become_ready)

    def _write_cfgr(self, value: int) -> None:
        new = (self.cfgr & ~CFGR_WRITABLE) | (value & CFGR_WRITABLE)
        if self.cr & PLLON:  # the PLL's source and multiplier are locked while it runs
            new = (new & ~PLL_CONFIG) | (self.cfgr & PLL_CONFIG)
        self.cfgr = new
        self._try_switch()

    def _ready(self, source: int) -> bool:
        if source == SW_HSI:
            return bool(self.cr & HSIRDY)
        if source == SW_HSE:
            return bool(self.cr & HSERDY)
        if source == SW_PLL:
            return bool(self.cr & PLLRDY)
        return False  # SW = 3 is not allowed: nothing switches

    def _try_switch(self) -> None:
        """SWS follows SW once the selected source is ready."""
        wanted = self.cfgr & 3
        if wanted != self.sysclk_source and self._ready(wanted):
            self.cfgr = (self.cfgr & ~(3 << 2)) | (wanted << 2)
        self._notify()

    def _notify(self) -> None:
        clocks = self._compute()
        if clocks != getattr(self, "_last", None):
            self._last = clocks
            if self.on_change is not None:
                self.on_change(clocks)
