"""The emulated STM32F103's peripheral models against the reference manual's rules (RM0008,
ARMv7-M): reset values, fields the hardware ignores, the order it imposes, and the timing
of what takes time. Each model runs alone on a scheduler with a hand-moved clock."""

from __future__ import annotations

import random

import pytest

from snakebot.core import ffi, lib
from snakebot.sim.mcu import flash as fl
from snakebot.sim.mcu import gpio, iwdg, nvic, rcc, systick, usart
from snakebot.sim.mcu.errors import McuFault, UnmodelledAccess
from snakebot.sim.mcu.schedule import Scheduler


class Clock:
    """A scheduler and a time that only the test moves (running the events due)."""

    def __init__(self) -> None:
        self.t = 0.0
        self.scheduler = Scheduler()

    def __call__(self) -> float:
        return self.t

    def advance(self, dt: float) -> None:
        end = self.t + dt
        while (nxt := self.scheduler.next_time()) is not None and nxt <= end:
            self.t = nxt
            self.scheduler.run_due(nxt)
        self.t = end


@pytest.fixture
def clock() -> Clock:
    return Clock()


# -- RCC -------------------------------------------------------------------------------------


def test_rcc_reset_values_and_pll_start(clock: Clock) -> None:
    r = rcc.Rcc(clock.scheduler, clock, hse_hz=8_000_000)
    assert r.read(rcc.CR, 4) == 0x83 and r.read(rcc.CFGR, 4) == 0
    r.write(rcc.CR, 4, r.cr | rcc.HSEON)
    clock.advance(rcc.HSE_STARTUP_S * 0.9)
    assert not r.read(rcc.CR, 4) & rcc.HSERDY  # a crystal takes its start-up time
    clock.advance(rcc.HSE_STARTUP_S * 0.2)
    assert r.read(rcc.CR, 4) & rcc.HSERDY
    r.write(rcc.CFGR, 4, (1 << 16) | (7 << 18) | (4 << 8))  # HSE x9, APB1 /2
    r.write(rcc.CR, 4, r.cr | rcc.PLLON)
    r.write(rcc.CFGR, 4, r.cfgr | rcc.SW_PLL)
    assert r.sysclk_source == rcc.SW_HSI  # SWS follows SW only once the PLL has locked
    clock.advance(rcc.PLL_LOCK_S * 1.01)
    assert r.sysclk_source == rcc.SW_PLL
    assert r.clocks() == rcc.Clocks(72_000_000, 72_000_000, 36_000_000, 72_000_000)


def test_rcc_refuses_what_the_hardware_refuses(clock: Clock) -> None:
    r = rcc.Rcc(clock.scheduler, clock, hse_hz=8_000_000)
    r.write(rcc.CFGR, 4, 7 << 18)  # HSI/2 x9
    r.write(rcc.CR, 4, r.cr | rcc.PLLON)
    clock.advance(1e-3)
    r.write(rcc.CFGR, 4, (r.cfgr & ~(0xF << 18)) | (14 << 18))  # the multiplier is locked
    assert (r.cfgr >> 18) & 0xF == 7
    r.write(rcc.CFGR, 4, r.cfgr | rcc.SW_PLL)
    assert r.sysclk_source == rcc.SW_PLL
    r.write(rcc.CR, 4, r.cr & ~rcc.PLLON)  # the PLL drives SYSCLK: it cannot be stopped
    assert r.cr & rcc.PLLON and r.cr & rcc.PLLRDY
    r.write(rcc.CFGR, 4, r.cfgr & ~3)  # back to the HSI, then it can
    r.write(rcc.CR, 4, r.cr & ~rcc.PLLON)
    assert not r.cr & (rcc.PLLON | rcc.PLLRDY)


def test_rcc_no_crystal_never_ready_and_csr_flags(clock: Clock) -> None:
    r = rcc.Rcc(clock.scheduler, clock, hse_hz=0)
    r.write(rcc.CR, 4, r.cr | rcc.HSEON)
    clock.advance(0.1)
    assert not r.cr & rcc.HSERDY
    assert r.read(rcc.CSR, 4) & (rcc.CSR_POR | rcc.CSR_PIN) == rcc.CSR_POR | rcc.CSR_PIN
    r.write(rcc.CSR, 4, rcc.CSR_RMVF)
    assert r.read(rcc.CSR, 4) & rcc.CSR_FLAGS == 0
    with pytest.raises(UnmodelledAccess):
        r.read(0x2C, 4)  # AHBSTR... nothing the firmware uses


# -- FLASH ---------------------------------------------------------------------------------


def _flash(stalls: list[float]) -> tuple[fl.FlashInterface, bytearray]:
    mem = bytearray(b"\x00" * 8192)

    def read(addr: int, n: int) -> bytes:
        return bytes(mem[addr - fl.FLASH_BASE : addr - fl.FLASH_BASE + n])

    def write(addr: int, data: bytes) -> None:
        mem[addr - fl.FLASH_BASE : addr - fl.FLASH_BASE + len(data)] = data

    f = fl.FlashInterface(
        size=len(mem),
        page=2048,
        protected_below=fl.FLASH_BASE + 2048,
        read=read,
        write=write,
        stall=stalls.append,
    )
    return f, mem


def test_flash_unlock_erase_program() -> None:
    stalls: list[float] = []
    f, mem = _flash(stalls)
    assert f.read(fl.CR, 4) == fl.CR_LOCK and f.read(fl.ACR, 4) == fl.ACR_RESET
    f.write(fl.CR, 4, fl.CR_PER)  # locked: ignored
    assert f.read(fl.CR, 4) == fl.CR_LOCK
    f.write(fl.KEYR, 4, fl.KEY1)
    f.write(fl.KEYR, 4, fl.KEY2)
    assert not f.read(fl.CR, 4) & fl.CR_LOCK
    f.write(fl.CR, 4, fl.CR_PER)
    f.write(fl.AR, 4, fl.FLASH_BASE + 4096 + 10)
    f.write(fl.CR, 4, fl.CR_PER | fl.CR_STRT)
    assert mem[4096:6144] == b"\xff" * 2048 and mem[6144] == 0 and stalls == [fl.PAGE_ERASE_S]
    assert f.read(fl.SR, 4) & fl.SR_EOP
    f.write(fl.CR, 4, fl.CR_PG)
    f.program(fl.FLASH_BASE + 4096, 2, 0x1234)
    assert mem[4096:4098] == b"\x34\x12"
    f.program(fl.FLASH_BASE + 4096, 2, 0x5678)  # not erased: PGERR, nothing written
    assert f.read(fl.SR, 4) & fl.SR_PGERR and mem[4096:4098] == b"\x34\x12"
    f.program(fl.FLASH_BASE + 4096, 2, 0)  # zero may always be written
    assert mem[4096:4098] == b"\0\0"
    f.write(fl.SR, 4, fl.SR_PGERR | fl.SR_EOP)  # write 1 to clear
    assert f.read(fl.SR, 4) == 0
    with pytest.raises(McuFault, match="half-word"):
        f.program(fl.FLASH_BASE + 4100, 4, 0)
    f.program(fl.FLASH_BASE + 100, 2, 0)  # the bootloader's page is protected
    assert f.read(fl.SR, 4) & fl.SR_WRPRTERR and mem[100] == 0


def test_flash_wrong_key_locks_until_reset_and_wait_states() -> None:
    f, _ = _flash([])
    f.write(fl.KEYR, 4, fl.KEY2)
    f.write(fl.KEYR, 4, fl.KEY1)
    f.write(fl.KEYR, 4, fl.KEY2)
    assert f.read(fl.CR, 4) & fl.CR_LOCK
    f.reset()
    f.write(fl.KEYR, 4, fl.KEY1)
    f.write(fl.KEYR, 4, fl.KEY2)
    assert not f.read(fl.CR, 4) & fl.CR_LOCK
    with pytest.raises(McuFault, match="without FLASH_CR PG"):
        f.program(fl.FLASH_BASE + 4096, 2, 0)
    with pytest.raises(McuFault, match="wait state"):
        f.check_clock(72_000_000)  # latency 0 at reset
    f.write(fl.ACR, 4, 2 | fl.ACR_PRFTBE)
    f.check_clock(72_000_000)
    with pytest.raises(McuFault, match="wait state"):
        f.write(fl.ACR, 4, 1 | fl.ACR_PRFTBE)  # lowered below what 72 MHz needs


# -- GPIO and AFIO -------------------------------------------------------------------------


def test_gpio_modes_bsrr_and_listeners() -> None:
    on = [True]
    port = gpio.GpioPort("B", lambda: on[0])
    heard: list[tuple[int, bool]] = []
    port.listen(lambda pin, level: heard.append((pin, level)))
    assert port.read(gpio.CRL, 4) == gpio.CR_RESET and port.read(gpio.IDR, 4) == 0
    port.write(gpio.CRL, 4, (gpio.CR_RESET & ~(0xF << 16)) | (0x3 << 16))  # PB4 output
    port.write(gpio.BSRR, 4, (1 << 4) | (1 << 20))  # set and reset at once: set wins
    assert port.read(gpio.ODR, 4) & 0x10 and heard == [(4, False), (4, True)]  # out, then set
    port.write(gpio.BRR, 4, 1 << 4)
    assert heard[-1] == (4, False)
    port.write(gpio.CRH, 4, (gpio.CR_RESET & ~0xF) | gpio.INPUT_PULL)  # PB8 pull-up
    port.write(gpio.BSRR, 4, 1 << 8)
    assert port.read(gpio.IDR, 4) & (1 << 8)
    port.drive(8, False)  # a button pulls it down
    assert not port.read(gpio.IDR, 4) & (1 << 8)
    on[0] = False
    with pytest.raises(UnmodelledAccess, match="clock off"):
        port.write(gpio.BSRR, 4, 1)


def test_gpio_idr_read_in_c_as_the_model_reads_it() -> None:
    # the firmware polls its buttons' IDR every tick: C serves the read from what the
    # model keeps there (ODR, the outputs, the pulled inputs) while the port's clock is
    # on, no pin is driven from outside and no byte a USART started in C waits
    on = [True]
    port = gpio.GpioPort("C", lambda: on[0])
    counter = ffi.new("mcu_counter *")
    port.fast.counter = counter
    value = ffi.new("uint64_t *")

    def in_c() -> int | None:
        return int(value[0]) if lib.mcu_gpio_read(port.fast, gpio.IDR, 4, value) else None

    # every input and output configuration: analog, floating, pulled; push-pull and open
    # drain, GPIO and alternate function, at each speed
    nibbles = [gpio.INPUT_ANALOG, gpio.INPUT_FLOATING, gpio.INPUT_PULL]
    nibbles += [cnf | speed for cnf in range(0, 16, 4) for speed in (1, 2, 3)]
    rng = random.Random(30)
    for _ in range(300):
        for reg in (gpio.CRL, gpio.CRH):
            port.write(reg, 4, sum(rng.choice(nibbles) << 4 * n for n in range(8)))
        port.write(gpio.ODR, 4, rng.getrandbits(16))
        assert in_c() == port.read(gpio.IDR, 4)
    port.write(gpio.CRL, 4, gpio.CR_RESET & ~0xF | gpio.INPUT_PULL)  # PC0 pulled up
    port.write(gpio.BSRR, 4, 1)
    assert in_c() == port.read(gpio.IDR, 4) and in_c() & 1
    port.drive(0, False)  # a button pulls it down: the model reads it
    assert in_c() is None and not port.read(gpio.IDR, 4) & 1
    port.drive(0, None)
    assert in_c() == port.read(gpio.IDR, 4) and in_c() & 1
    counter.undrained = 1  # a USART's bytes go first, through the model
    assert in_c() is None
    counter.undrained = 0
    on[0] = False
    port.clock_changed()
    assert in_c() is None  # the model's (reads as zero, or an error when strict)


def test_afio_remap_and_write_only_swj() -> None:
    a = gpio.Afio(lambda: True)
    a.write(gpio.MAPR, 4, gpio.MAPR_USART1_REMAP | (2 << 24))
    assert a.usart1_remapped and a.swj == 2
    assert a.read(gpio.MAPR, 4) == gpio.MAPR_USART1_REMAP  # SWJ_CFG reads as zero


# -- USART ---------------------------------------------------------------------------------


def _usart(clock: Clock, lines: list[bool], sent: list[tuple[int, float]]) -> usart.Usart:
    u = usart.Usart(
        "USART1",
        0x40013800,
        scheduler=clock.scheduler,
        now=clock,
        pclk=lambda: 72_000_000,
        irq=lines.append,
        clock_on=lambda: True,
        on_tx=lambda b, s, e, baud: sent.append((b, s)),
    )
    u.write(usart.BRR, 4, 72)  # 1 Mbps
    return u


def test_usart_transmit_timing(clock: Clock) -> None:
    lines: list[bool] = []
    sent: list[tuple[int, float]] = []
    u = _usart(clock, lines, sent)
    assert u.read(usart.SR, 4) == usart.TXE | usart.TC
    u.write(usart.CR1, 4, usart.CR1_UE | usart.CR1_TE)  # an idle frame goes first
    u.write(usart.DR, 4, 0x55)
    assert u.read(usart.SR, 4) & usart.TXE == 0  # waits in TDR behind the idle frame
    u.write(usart.DR, 4, 0x66)  # written with TXE clear: replaces it, 0x55 is lost
    clock.advance(10e-6)
    assert sent == [(0x66, pytest.approx(10e-6))]
    clock.advance(100e-6)
    assert u.read(usart.SR, 4) & usart.TC


def test_usart_back_to_back_bytes_and_tc(clock: Clock) -> None:
    lines: list[bool] = []
    sent: list[tuple[int, float]] = []
    u = _usart(clock, lines, sent)
    u.write(usart.CR1, 4, usart.CR1_UE | usart.CR1_TE)
    clock.advance(10e-6)  # the idle frame
    u.read(usart.SR, 4)
    u.write(usart.DR, 4, 1)  # straight to the shift register: TXE stays set
    assert u.read(usart.SR, 4) & (usart.TXE | usart.TC) == usart.TXE
    u.write(usart.DR, 4, 2)
    assert not u.read(usart.SR, 4) & usart.TXE
    clock.advance(9.9e-6)
    assert [b for b, _ in sent] == [1] and not u.sr & usart.TXE
    clock.advance(0.2e-6)  # byte 1's stop bit is out: byte 2 starts
    assert [s for _, s in sent] == [pytest.approx(10e-6), pytest.approx(20e-6)]
    clock.advance(10e-6)
    assert u.sr & usart.TC  # 10 bit times at 1 Mbps each


def test_usart_receive_overrun_and_irq(clock: Clock) -> None:
    lines: list[bool] = []
    u = _usart(clock, lines, [])
    u.write(usart.CR1, 4, usart.CR1_UE | usart.CR1_RE | usart.CR1_RXNEIE)
    u.receive(0x41)
    assert lines[-1] is True and u.read(usart.SR, 4) & usart.RXNE
    u.receive(0x42)  # RXNE still set: lost, ORE
    assert u.sr & usart.ORE and u.overruns == 1
    assert u.read(usart.SR, 4) & usart.ORE
    assert u.read(usart.DR, 4) == 0x41  # SR then DR clears RXNE and ORE
    assert not u.sr & (usart.RXNE | usart.ORE) and lines[-1] is False
    u.feed(b"ab")
    clock.advance(10e-6)
    assert u.read(usart.DR, 4) == ord("a")
    clock.advance(10e-6)
    assert u.read(usart.DR, 4) == ord("b")


def test_usart_bytes_before_a_rate_is_set_are_lost_and_later_ones_received(clock: Clock) -> None:
    """The PC may send while the firmware is still starting (the flasher PINGs the new
    firmware right after GO): those bytes are lost, and the bytes sent once the USART is
    set up are received (they once waited forever behind an event at infinity)."""
    u = usart.Usart(
        "USART3",
        0x40004800,
        scheduler=clock.scheduler,
        now=clock,
        pclk=lambda: 36_000_000,
        irq=lambda level: None,
        clock_on=lambda: True,
    )
    u.feed(b"early")  # from reset: BRR 0, no rate
    clock.advance(1.0)
    assert u.lost == 5 and u.received == 0 and u.inbox == 0
    u.write(usart.BRR, 4, 625)  # 57600 baud
    u.write(usart.CR1, 4, usart.CR1_UE | usart.CR1_RE)
    u.feed(b"ok")
    clock.advance(2 * u.frame_s())
    assert u.received == 2 and u.overruns == 1  # unread: the second overran the first
    assert u.read(usart.DR, 4) == ord("o")


def test_usart_unmodelled_modes_are_errors(clock: Clock) -> None:
    u = _usart(clock, [], [])
    with pytest.raises(UnmodelledAccess):
        u.write(usart.CR1, 4, usart.CR1_UE | usart.CR1_M)  # 9 data bits
    with pytest.raises(UnmodelledAccess):
        u.write(usart.CR3, 4, 1 << 3)  # HDSEL


# -- SysTick ---------------------------------------------------------------------------------


def test_systick_counts_reloads_and_pends(clock: Clock) -> None:
    pends: list[float] = []
    s = systick.SysTick(clock.scheduler, clock, pend=lambda: pends.append(clock.t), hclk_hz=1000)
    assert s.read(systick.CSR, 4) == 0
    s.write(systick.RVR, 4, 9)
    s.write(systick.CVR, 4, 123)  # any write clears it
    assert s.read(systick.CVR, 4) == 0
    s.write(systick.CSR, 4, systick.ENABLE | systick.TICKINT | systick.CLKSOURCE)
    clock.advance(0.0015)
    assert s.read(systick.CVR, 4) == 9  # reloaded on the first step
    clock.advance(0.0090)
    assert pends == [pytest.approx(0.010)]  # reaches 0 after RVR + 1 steps
    assert s.read(systick.CSR, 4) & systick.COUNTFLAG
    assert not s.read(systick.CSR, 4) & systick.COUNTFLAG  # reading CSR cleared it
    clock.advance(0.020)
    assert len(pends) == 3
    s.write(systick.CSR, 4, systick.ENABLE)  # HCLK/8 without TICKINT: no more pends
    clock.advance(0.2)
    assert len(pends) == 3 and s.fired > 3


# -- NVIC and SCB -----------------------------------------------------------------------------


def test_nvic_priorities_prigroup_and_preemption() -> None:
    n = nvic.Nvic()
    n.write(nvic.IPR + 37, 1, 0x1F)  # the low nibble is not implemented
    assert n.read(nvic.IPR + 37, 1) == 0x10
    n.write(nvic.IPR + 36, 4, 0x2030_1040)  # a word at once: IRQs 36..39
    n.write(nvic.ISER + 4, 4, 1 << (39 - 32) | 1 << (37 - 32))
    n.set_line(39, True)
    n.set_line(37, True)
    assert n.takeable(primask=False) == 16 + 37  # priority 0x30 < 0x20? no: 0x10 < 0x20
    assert n.takeable(primask=True) is None
    n.activate(16 + 37)
    assert n.takeable(False) is None  # 39 (0x20) cannot preempt 37 (0x10)
    n.set_line(37, False)
    n.deactivate()
    assert n.takeable(False) == 16 + 39
    n.write(nvic.AIRCR, 4, (nvic.VECTKEY << 16) | (7 << 8))  # PRIGROUP 7: no preemption
    n.activate(16 + 39)
    n.write(nvic.ISPR + 4, 4, 1 << (37 - 32))
    assert n.takeable(False) is None
    assert n.read(nvic.AIRCR, 4) == 0xFA05_0700


def test_nvic_level_lines_repend_and_aircr_key() -> None:
    resets: list[int] = []
    n = nvic.Nvic(on_reset=lambda: resets.append(1))
    n.write(nvic.ISER + 4, 4, 1 << (39 - 32))
    n.set_line(39, True)
    n.activate(16 + 39)
    n.deactivate()  # the line is still high: pending again
    assert n.pending >> (16 + 39) & 1
    n.write(nvic.ICPR + 4, 4, 1 << (39 - 32))
    assert not n.pending
    n.write(nvic.AIRCR, 4, nvic.AIRCR_SYSRESETREQ)  # no key: ignored
    assert resets == []
    n.write(nvic.AIRCR, 4, (nvic.VECTKEY << 16) | nvic.AIRCR_SYSRESETREQ)
    assert resets == [1]
    n.write(nvic.VTOR, 4, 0x0800_3011)
    assert n.read(nvic.VTOR, 4) == 0x0800_3000
    n.write(nvic.ICSR, 4, nvic.ICSR_PENDSTSET)
    assert n.read(nvic.ICSR, 4) & nvic.ICSR_PENDSTSET and n.best_pending() == nvic.SYSTICK
    assert n.read(nvic.CPUID, 4) == nvic.CPUID_VALUE
    with pytest.raises(UnmodelledAccess):
        n.write(nvic.SCR, 4, 1 << 2)  # SLEEPDEEP


# -- IWDG ------------------------------------------------------------------------------------


def test_iwdg_protection_timeout_and_feeds(clock: Clock) -> None:
    expired: list[float] = []
    w = iwdg.Iwdg(clock.scheduler, clock, on_timeout=lambda: expired.append(clock.t))
    w.write(iwdg.PR, 4, 3)  # not unlocked: ignored
    assert w.read(iwdg.PR, 4) == 0
    w.write(iwdg.KR, 4, iwdg.KEY_ACCESS)
    w.write(iwdg.PR, 4, 3)  # /32
    w.write(iwdg.RLR, 4, 624)  # 625 * 32 / 40 kHz = 0.5 s
    assert w.read(iwdg.SR, 4) == iwdg.PVU | iwdg.RVU
    clock.advance(1e-3)
    assert w.read(iwdg.SR, 4) == 0
    w.write(iwdg.KR, 4, iwdg.KEY_START)
    clock.advance(0.4)
    w.write(iwdg.KR, 4, iwdg.KEY_RELOAD)
    clock.advance(0.49)
    assert expired == []
    clock.advance(0.02)
    assert expired == [pytest.approx(0.901)]  # 0.5 s after the last reload
    assert w.largest_gap == pytest.approx(0.4)
