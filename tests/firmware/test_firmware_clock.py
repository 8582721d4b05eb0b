"""The clock driver (firmware/hal/hal_clock.c) against a register model of the STM32F1
RCC: with a working crystal it reaches 72 MHz through the PLL; with a dead crystal it
falls back to the HSI through the PLL; where nothing ever becomes ready (QEMU's
unimplemented RCC reads 0) it still returns, on the bare HSI, instead of hanging."""

from __future__ import annotations

from firmware_support import RegisterModels, hal_fixture

RCC_CR, RCC_CFGR = 0x40021000, 0x40021004
FLASH_ACR = 0x40022000
HSION, HSIRDY, HSEON, HSERDY, PLLON, PLLRDY = 1, 2, 1 << 16, 1 << 17, 1 << 24, 1 << 25
POLLS = 200

HSE_PLL, HSI_PLL, HSI = 0, 1, 2

CDEF = """
typedef struct {
    uint32_t sysclk_hz; uint32_t hclk_hz; uint32_t pclk1_hz; uint32_t pclk2_hz; int source;
} hal_clocks_t;
hal_clocks_t hal_clock_init(uint32_t hse_hz, unsigned pll_mul);
"""


PLLCONF = (1 << 16) | (1 << 17) | (0xF << 18)  # PLLSRC, PLLXTPRE, PLLMUL: PLL off only
SW_PLL = 2

# What the ROBOTIS bootloader may leave behind: the crystal on, the PLL running from it
# (x6, not our x9, so a configuration the hardware ignored shows) and driving SYSCLK.
BOOTLOADER_CR = HSION | HSIRDY | HSEON | HSERDY | PLLON | PLLRDY
BOOTLOADER_CFGR = SW_PLL | (SW_PLL << 2) | (1 << 16) | ((6 - 2) << 18) | (4 << 8)


class RccModel:
    """CR/CFGR of the RCC and the flash ACR, with the hardware's rules: an oscillator
    becomes ready `delay` reads after it is switched on, or never (None); the PLL reports
    unlocked `pll_stop_delay` reads after PLLON is cleared (never: None); the switch status
    follows SW after `sw_delay` reads towards the PLL, `hsi_switch_delay` towards the HSI.
    Writes the real chip ignores are ignored here too, and listed in `ignored`: PLLON = 0
    while the PLL drives SYSCLK, the PLL's source and multiplier while it runs. Every
    access is logged, in order, in `log` as (op, addr, value)."""

    def __init__(
        self,
        hse_delay=5,
        pll_delay=5,
        sw_delay=1,
        everything_reads_zero=False,
        pll_stop_delay=1,
        hsi_switch_delay=1,
        bootloader_left=False,
    ):
        self.cr = BOOTLOADER_CR if bootloader_left else HSION | HSIRDY
        self.cfgr = BOOTLOADER_CFGR if bootloader_left else 0
        self.acr = 0x32 if bootloader_left else 0x30
        self.delays = {HSERDY: hse_delay, PLLRDY: pll_delay}
        self.countdown: dict[int, int] = {}  # ready bit -> reads until it sets
        self.pll_stop_delay = pll_stop_delay
        self.pll_stop_countdown = None
        self.sw_delay = sw_delay
        self.hsi_switch_delay = hsi_switch_delay
        self.sw_countdown = 0
        self.zero = everything_reads_zero
        self.acr_when_pll_selected = None
        self.log: list[tuple[str, int, int]] = []
        self.ignored: list[str] = []

    def read32(self, addr):
        value = self._read(addr)
        self.log.append(("r", addr, value))
        return value

    def _read(self, addr):
        if self.zero:
            return 0
        if addr == RCC_CR:
            for rdy, left in list(self.countdown.items()):
                if left <= 0:
                    self.cr |= rdy
                    del self.countdown[rdy]
                else:
                    self.countdown[rdy] = left - 1
            if self.pll_stop_countdown is not None:
                if self.pll_stop_countdown <= 0:
                    self.cr &= ~PLLRDY
                    self.pll_stop_countdown = None
                else:
                    self.pll_stop_countdown -= 1
            return self.cr
        if addr == RCC_CFGR:
            if self.sw_countdown > 0:
                self.sw_countdown -= 1
            else:
                self.cfgr = (self.cfgr & ~0xC) | ((self.cfgr & 3) << 2)
            return self.cfgr
        if addr == FLASH_ACR:
            return self.acr
        raise AssertionError(f"read of {addr:#x}")

    def write32(self, addr, value):
        self.log.append(("w", addr, value))
        if addr == RCC_CR:
            self._write_cr(value)
        elif addr == RCC_CFGR:
            self._write_cfgr(value)
        elif addr == FLASH_ACR:
            self.acr = value
        elif not self.zero:
            raise AssertionError(f"write of {addr:#x}")

    def _write_cr(self, value):
        if self.cr & PLLON and not value & PLLON and (self.cfgr >> 2) & 3 == SW_PLL:
            self.ignored.append("PLLON cleared while the PLL drives SYSCLK")
            value |= PLLON
        ready = self.cr & (HSIRDY | HSERDY | PLLRDY)  # read-only bits
        if value & HSEON and not self.cr & HSEON and self.delays[HSERDY] is not None:
            self.countdown[HSERDY] = self.delays[HSERDY]
        if not value & HSEON:
            ready &= ~HSERDY
            self.countdown.pop(HSERDY, None)
        if value & PLLON and not self.cr & PLLON:
            self.pll_stop_countdown = None
            if self.delays[PLLRDY] is not None:
                self.countdown[PLLRDY] = self.delays[PLLRDY]
        if not value & PLLON and self.cr & PLLON:
            self.countdown.pop(PLLRDY, None)
            if self.pll_stop_delay is not None:
                self.pll_stop_countdown = self.pll_stop_delay
        self.cr = (value & ~(HSIRDY | HSERDY | PLLRDY)) | ready

    def _write_cfgr(self, value):
        if (value ^ self.cfgr) & PLLCONF and self.cr & (PLLON | PLLRDY):
            self.ignored.append("PLL configured while it runs")
            value = (value & ~PLLCONF) | (self.cfgr & PLLCONF)
        if (value & 3) != (self.cfgr & 3):
            to_pll = (value & 3) == SW_PLL
            self.sw_countdown = self.sw_delay if to_pll else self.hsi_switch_delay
            if to_pll:
                self.acr_when_pll_selected = self.acr
        self.cfgr = (value & ~0xC) | (self.cfgr & 0xC)


MODELS = RegisterModels()


hal = hal_fixture(
    "_hal_clock_host",
    ["hal_clock.c"],
    ["hal_clock.h"],
    CDEF,
    MODELS,
    defines=[("HAL_CLOCK_READY_POLLS", str(POLLS))],
)


def run(hal, model: RccModel):
    with MODELS.use(model):
        c = hal.lib.hal_clock_init(8_000_000, 9)
        return (c.sysclk_hz, c.hclk_hz, c.pclk1_hz, c.pclk2_hz, c.source)


def pllmul(cfgr: int) -> int:
    return ((cfgr >> 18) & 0xF) + 2


def test_crystal_gives_72_mhz(hal):
    m = RccModel()
    assert run(hal, m) == (72_000_000, 72_000_000, 36_000_000, 72_000_000, HSE_PLL)
    assert m.cfgr & 3 == 2 and m.cfgr & (1 << 16)  # PLL, fed by the HSE
    assert pllmul(m.cfgr) == 9
    assert (m.cfgr >> 8) & 7 == 4  # APB1 /2: it may not exceed 36 MHz
    assert (m.cfgr >> 11) & 7 == 0 and (m.cfgr >> 4) & 0xF == 0  # APB2, AHB /1
    assert m.acr_when_pll_selected & 7 == 2  # two wait states before the clock went up


def test_dead_crystal_falls_back_to_hsi_pll(hal):
    m = RccModel(hse_delay=None)
    assert run(hal, m) == (64_000_000, 64_000_000, 32_000_000, 64_000_000, HSI_PLL)
    assert not m.cr & HSEON  # the crystal oscillator is switched off again
    assert not m.cfgr & (1 << 16) and pllmul(m.cfgr) == 16


def test_no_pll_either_stays_on_hsi(hal):
    m = RccModel(hse_delay=None, pll_delay=None)
    assert run(hal, m) == (8_000_000, 8_000_000, 8_000_000, 8_000_000, HSI)
    assert m.cfgr & 3 == 0 and not m.cr & PLLON
    assert m.acr & 7 == 0


def test_switch_that_never_completes_is_abandoned(hal):
    m = RccModel(sw_delay=10 * POLLS)
    sysclk, *_, source = run(hal, m)
    assert (sysclk, source) == (8_000_000, HSI)
    assert m.cfgr & 3 == 0


def test_qemu_rcc_reading_zero_returns_instead_of_hanging(hal):
    assert run(hal, RccModel(everything_reads_zero=True))[4] == HSI


def first(log, pred, after=-1):
    """The index of the first log entry after `after` that satisfies `pred`."""
    return next(i for i, e in enumerate(log) if i > after and pred(e))


def test_bootloader_pll_is_left_only_after_sysclk_is_on_hsi(hal):
    m = RccModel(bootloader_left=True, hsi_switch_delay=3, pll_stop_delay=4)
    assert run(hal, m) == (72_000_000, 72_000_000, 36_000_000, 72_000_000, HSE_PLL)
    assert pllmul(m.cfgr) == 9  # our multiplier, not the bootloader's x6
    assert m.ignored == []
    log = m.log
    on_hsi = first(log, lambda e: e[:2] == ("r", RCC_CFGR) and (e[2] >> 2) & 3 == 0)
    pll_off = first(log, lambda e: e[:2] == ("w", RCC_CR) and not e[2] & PLLON)
    assert on_hsi < pll_off  # SYSCLK was seen on the HSI before the PLL was stopped
    unlocked = first(log, lambda e: e[:2] == ("r", RCC_CR) and not e[2] & PLLRDY, pll_off)
    configured = first(log, lambda e: e[:2] == ("w", RCC_CFGR) and pllmul(e[2]) == 9)
    assert unlocked < configured  # the PLL reported unlocked before it was configured


def test_pll_that_never_unlocks_is_not_configured(hal):
    m = RccModel(bootloader_left=True, pll_stop_delay=None)
    assert run(hal, m) == (8_000_000, 8_000_000, 8_000_000, 8_000_000, HSI)
    assert m.ignored == [] and m.cfgr & 3 == 0 and pllmul(m.cfgr) == 6


def test_sysclk_that_never_leaves_the_pll_keeps_the_bootloader_clock(hal):
    m = RccModel(bootloader_left=True, hsi_switch_delay=10 * POLLS)
    # The PLL cannot be touched, so the clock stays the bootloader's: 8 MHz x6.
    assert run(hal, m) == (48_000_000, 48_000_000, 24_000_000, 48_000_000, HSE_PLL)
    assert m.ignored == [] and m.cr & PLLON and pllmul(m.cfgr) == 6
    assert m.acr & 7 == 2  # the most wait states: right for whatever SYSCLK is
