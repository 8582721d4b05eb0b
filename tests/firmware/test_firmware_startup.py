"""The reset handler's first job (firmware/hal/hal_startup.c): whatever interrupt state the
bootloader left (NVIC lines enabled and pending, SysTick counting with its interrupt on, a
tick pending) is silenced before interrupts are enabled, so no leftover interrupt reaches
the default handler, which resets the MCU into a boot loop. Checked against a register
model of the NVIC and SysTick, and in the built images' reset handler."""

from __future__ import annotations

import subprocess

import pytest
from firmware_support import (
    CM530_DIR,
    QEMU_DIR,
    RegisterModels,
    build_firmware,
    hal_fixture,
)

SYST_CSR, ICSR = 0xE000E010, 0xE000ED04
ICER, ICPR = 0xE000E180, 0xE000E280
PENDSTCLR, PENDSVCLR = 1 << 25, 1 << 27
SYST_ENABLE, SYST_TICKINT = 1, 2
USART1, USART3, TIM2 = 37, 39, 28  # lines a bootloader plausibly used

CDEF = """
#define HAL_IRQ_COUNT ...
void hal_quiet_interrupts(void);
"""


class NvicModel:
    """The NVIC's enable and pending bits for `lines` interrupt lines (bits of lines the
    MCU does not have read as zero and ignore writes), SysTick's control register and the
    pending SysTick/PendSV bits of ICSR, starting from the bootloader's leftovers. Every
    write is logged in order."""

    def __init__(self, lines: int):
        self.lines = lines
        left = (1 << USART1) | (1 << USART3) | (1 << TIM2)
        self.enabled = left
        self.pending = left | (1 << (lines - 1))  # the last line too: the count matters
        self.systick = SYST_ENABLE | SYST_TICKINT
        self.tick_pending = self.pendsv_pending = True
        self.log: list[tuple[int, int]] = []

    def _word(self, addr: int, base: int) -> int | None:
        n = (addr - base) // 4
        return n if 0 <= n < 16 else None

    def read32(self, addr):
        raise AssertionError(f"read of {addr:#x}")

    def write32(self, addr, value):
        self.log.append((addr, value))
        real = (1 << self.lines) - 1
        if addr == SYST_CSR:
            self.systick = value
        elif addr == ICSR:
            self.tick_pending &= not value & PENDSTCLR
            self.pendsv_pending &= not value & PENDSVCLR
        elif (n := self._word(addr, ICER)) is not None:
            self.enabled &= ~((value << 32 * n) & real)
        elif (n := self._word(addr, ICPR)) is not None:
            self.pending &= ~((value << 32 * n) & real)
        else:
            raise AssertionError(f"write of {addr:#x}")


MODELS = RegisterModels()

hal = hal_fixture("_hal_startup_host", ["hal_startup.c"], ["hal_regs.h"], CDEF, MODELS)


def test_bootloader_leftovers_are_silenced(hal):
    m = NvicModel(hal.lib.HAL_IRQ_COUNT)
    with MODELS.use(m):
        hal.lib.hal_quiet_interrupts()
    assert m.enabled == 0 and m.pending == 0
    assert not m.systick & (SYST_ENABLE | SYST_TICKINT)
    assert not m.tick_pending and not m.pendsv_pending


def test_every_line_is_disabled_before_any_is_cleared(hal):
    m = NvicModel(hal.lib.HAL_IRQ_COUNT)
    with MODELS.use(m):
        hal.lib.hal_quiet_interrupts()
    addrs = [a for a, _ in m.log]
    words = (hal.lib.HAL_IRQ_COUNT + 31) // 32
    disables = [addrs.index(ICER + 4 * n) for n in range(words)]
    clears = [addrs.index(ICPR + 4 * n) for n in range(words)]
    assert max(disables) < min(clears)
    assert addrs.index(SYST_CSR) < min(clears)  # a running SysTick could pend again


@pytest.mark.parametrize("board_dir", [CM530_DIR, QEMU_DIR], ids=["cm530", "qemu"])
def test_reset_handler_silences_interrupts_before_enabling_them(board_dir):
    build_firmware()
    out = subprocess.run(
        ["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", str(board_dir / "firmware.elf")],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    body = out.split("<hal_reset_continue>:\n", 1)[1].split("\n\n", 1)[0]
    code = [line.split("\t", 1)[1] for line in body.splitlines() if "\t" in line]
    quiet = next(i for i, c in enumerate(code) if c.endswith("<hal_quiet_interrupts>"))
    enable = next(i for i, c in enumerate(code) if c.startswith("cpsie"))
    main = next(i for i, c in enumerate(code) if c.endswith("<main>"))
    assert quiet < enable < main
