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


class RccModel:
    """CR/CFGR of the RCC and the flash ACR. Each oscillator becomes ready `delay` reads
    after it is switched on, or never (None); the switch status follows SW likewise."""

    def __init__(self, hse_delay=5, pll_delay=5, sw_delay=1, everything_reads_zero=False):
        self.cr = HSION | HSIRDY
        self.cfgr = 0
        self.acr = 0x30
        self.delays = {HSERDY: hse_delay, PLLRDY: pll_delay}
        self.countdown: dict[int, int] = {}
        self.sw_delay = sw_delay
        self.sw_countdown = 0
        self.zero = everything_reads_zero
        self.acr_when_pll_selected = None

    def read32(self, addr):
        if self.zero:
            return 0
        if addr == RCC_CR:
            for rdy, left in list(self.countdown.items()):
                if left <= 0:
                    self.cr |= rdy
                    del self.countdown[rdy]
                else:
                    self.countdown[rdy] = left - 1
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
        if addr == RCC_CR:
            ready = self.cr & (HSIRDY | HSERDY | PLLRDY)  # read-only bits
            for on, rdy in ((HSEON, HSERDY), (PLLON, PLLRDY)):
                if value & on and not self.cr & on and self.delays[rdy] is not None:
                    self.countdown[rdy] = self.delays[rdy]
                if not value & on:
                    ready &= ~rdy
                    self.countdown.pop(rdy, None)
            self.cr = (value & ~(HSIRDY | HSERDY | PLLRDY)) | ready
        elif addr == RCC_CFGR:
            if (value & 3) == 2 and (self.cfgr & 3) != 2:
                self.sw_countdown = self.sw_delay
                self.acr_when_pll_selected = self.acr
            self.cfgr = (value & ~0xC) | (self.cfgr & 0xC)
        elif addr == FLASH_ACR:
            self.acr = value
        elif not self.zero:
            raise AssertionError(f"write of {addr:#x}")


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
