"""The STM32F103RE: a Cortex-M3 (:mod:`snakebot.sim.mcu.cpu`) with 512 KB of flash at
0x08000000, 64 KB of RAM at 0x20000000 and the peripherals the firmware uses, each a
register model in its own module, on one clock (:mod:`snakebot.sim.mcu.schedule`).

The memory map holds only what is modelled: flash, RAM, RCC, the flash interface,
GPIOA-D, AFIO, USART1, USART3, IWDG and the system control space. Any other address
faults (:class:`~snakebot.sim.mcu.errors.McuFault`), and a modelled peripheral's
unmodelled register is :class:`~snakebot.sim.mcu.errors.UnmodelledAccess` in strict mode.
Flash reads at 0x00000000 (the boot alias) are not mapped: the machine starts the CPU
from a vector table it is given (:meth:`Stm32f103.boot`), as the ROBOTIS bootloader
starts the application.

A reset (SYSRESETREQ, the watchdog) resets every peripheral and the core and calls
``on_reset(kind)``, which decides where the CPU starts again (the board runs its
bootloader's hand-over).
"""

from __future__ import annotations

import ctypes
import functools
import math
from collections.abc import Callable

from snakebot.core import lib
from snakebot.facts.memory import CM530_FLASH_SIZE as FLASH_SIZE
from snakebot.facts.memory import CM530_RAM_SIZE as RAM_SIZE
from snakebot.facts.memory import FLASH_BASE, RAM_BASE
from snakebot.sim.mcu import rcc as rcc_mod
from snakebot.sim.mcu.cpu import (
    UC_HOOK_MEM_FETCH_PROT,
    UC_HOOK_MEM_WRITE_PROT,
    UC_PROT_ALL,
    UC_PROT_EXEC,
    UC_PROT_READ,
    UC_PROT_WRITE,
    Cpu,
    Uc,
    unmasking_sites,
)
from snakebot.sim.mcu.errors import McuFault
from snakebot.sim.mcu.flash import FlashInterface
from snakebot.sim.mcu.gpio import Afio, GpioPort
from snakebot.sim.mcu.iwdg import Iwdg
from snakebot.sim.mcu.nvic import SYSTEM_EXCEPTIONS, SYSTICK, Nvic
from snakebot.sim.mcu.rcc import Clocks, Rcc
from snakebot.sim.mcu.regs import Peripheral
from snakebot.sim.mcu.schedule import Scheduler
from snakebot.sim.mcu.systick import SysTick
from snakebot.sim.mcu.usart import Usart

USART1_BASE, USART3_BASE = 0x40013800, 0x40004800
USART1_IRQ, USART3_IRQ = 37, 39
RCC_APB2_BITS = {"AFIO": 0, "A": 2, "B": 3, "C": 4, "D": 5, "USART1": 14}
RCC_APB1_BITS = {"USART3": 18}
RESET_SOFTWARE, RESET_WATCHDOG, RESET_PIN, RESET_POWER = "software", "watchdog", "pin", "power"


class Stm32f103:
    """One chip. ``hse_hz``: the board's crystal. ``protected_below``: flash below this
    address is write-protected (the bootloader's pages). ``strict``: unmodelled accesses
    are errors (tests) or read as zero and are counted (a long-running server)."""

    def __init__(
        self,
        *,
        hse_hz: int,
        protected_below: int = FLASH_BASE,
        page_size: int = 2048,
        strict: bool = True,
        lsi_hz: float | None = None,
        on_reset: Callable[[str], None] | None = None,
    ) -> None:
        self.strict = strict
        self.on_reset = on_reset
        self.scheduler = Scheduler()
        self.scheduler.on_earlier = self._event_scheduled
        self.resets: list[tuple[float, str]] = []
        self._reset_request: str | None = None
        self.stalled_s = 0.0

        self.nvic = Nvic(on_reset=self._software_reset)
        self.cpu = Cpu(self.nvic)
        self._t_end = 0.0  # where the current run_until ends
        self.cpu.on_sleep = self._sleep_in_run
        self._clock = self.cpu.counter  # the time base lives beside the count (mcu_count.h)
        self._clock.t0 = 0.0
        self._clock.c0 = 0
        self._clock.hz = rcc_mod.HSI_HZ
        self.now: Callable[[], float] = functools.partial(lib.mcu_now, self._clock)
        """The chip's time (seconds since it was powered): the C function itself, no Python
        frame (the peripherals read it at almost every access)."""
        uc = self.cpu.uc
        # the flash's bytes in memory of ours: programming writes them here, where unicorn's
        # uc_mem_write to a read-only region would lift and restore its protection, each
        # time rebuilding the whole address map (far more than the program step itself)
        self._flash_bytes = (ctypes.c_ubyte * FLASH_SIZE).from_buffer(
            bytearray(b"\xff" * FLASH_SIZE)
        )
        uc.mem_map_ptr(
            FLASH_BASE, FLASH_SIZE, UC_PROT_READ | UC_PROT_EXEC, ctypes.addressof(self._flash_bytes)
        )
        # RAM not executable until the CPU first fetches from it (_fetch_from_ram makes it so
        # for good): unicorn 2.1 sends every store to memory that may hold translated code
        # through its slow path, which also looks for that code to drop (about 1 in 5 of
        # the firmware's instructions is a store)
        uc.mem_map(RAM_BASE, RAM_SIZE, UC_PROT_READ | UC_PROT_WRITE)
        uc.hook_add(
            UC_HOOK_MEM_FETCH_PROT,
            self._fetch_from_ram,
            begin=RAM_BASE,
            end=RAM_BASE + RAM_SIZE - 1,
        )

        self.systick = SysTick(
            self.scheduler,
            self.now,
            pend=functools.partial(lib.mcu_nvic_pend, self.nvic.c, SYSTICK),
            strict=strict,
        )
        self.nvic.systick = self.systick
        self.nvic.strict = strict
        self.rcc = Rcc(self.scheduler, self.now, hse_hz=hse_hz, strict=strict)
        self.flash = FlashInterface(
            size=FLASH_SIZE,
            page=page_size,
            protected_below=protected_below,
            read=lambda a, n: bytes(uc.mem_read(a, n)),
            write=self._write_flash,
            stall=self.stall,
            strict=strict,
        )
        self.rcc.on_change = self._clocks_changed
        self.gpio = {
            letter: GpioPort(letter, self._apb2(letter), strict=strict) for letter in "ABCD"
        }
        self.afio = Afio(self._apb2("AFIO"), strict=strict)
        self.usart1 = self._usart("USART1", USART1_BASE, USART1_IRQ, "apb2")
        self.usart3 = self._usart("USART3", USART3_BASE, USART3_IRQ, "apb1")
        self._usarts = (self.usart1, self.usart3)
        for i, u in enumerate(self._usarts):  # their frames end in C (mcu_usart.h)
            self._clock.timed[i] = u.fast
            u.time_in_c(self._clock)
        self._clock.n_timed = len(self._usarts)
        self.rcc.on_gate = self._clock_gates_changed
        self.iwdg = Iwdg(
            self.scheduler,
            self.now,
            on_timeout=self._watchdog_reset,
            strict=strict,
            **({} if lsi_hz is None else {"lsi_hz": lsi_hz}),
        )
        self.peripherals: list[Peripheral] = [
            self.rcc,
            self.flash,
            *self.gpio.values(),
            self.afio,
            self.usart1,
            self.usart3,
            self.iwdg,
            self.nvic,
        ]
        for p in self.peripherals:
            self._map(p)
        uc.hook_add(UC_HOOK_MEM_WRITE_PROT, self._flash_write)

    # -- wiring helpers ------------------------------------------------------------------------

    def _apb2(self, name: str) -> Callable[[], bool]:
        bit = 1 << RCC_APB2_BITS[name]
        rcc = self.rcc
        return lambda: bool(rcc.apb2enr & bit)

    def _usart(self, name: str, base: int, irq: int, bus: str) -> Usart:
        bit = 1 << (RCC_APB2_BITS if bus == "apb2" else RCC_APB1_BITS)[name]
        rcc = self.rcc

        def pclk() -> int:
            c = rcc.clocks()
            return c.pclk2 if bus == "apb2" else c.pclk1

        def clock_on() -> bool:  # asked at every register access: the bus chosen once
            return bool(rcc.apb2enr & bit)

        if bus != "apb2":

            def clock_on() -> bool:
                return bool(rcc.apb1enr & bit)

        return Usart(
            name,
            base,
            scheduler=self.scheduler,
            now=self.now,
            pclk=pclk,
            irq=functools.partial(lib.mcu_nvic_set_line, self.nvic.c, irq),
            clock_on=clock_on,
            strict=self.strict,
            nvic_line=(self.nvic.c, irq),
        )

    def _map(self, p: Peripheral) -> None:
        # ctypes callbacks of our own rather than Uc.mmio_map's: two Python calls fewer on
        # every register access, which the firmware's polling loops make by the thousand
        fail = self.cpu.fail
        peripheral_read, peripheral_write = p.read, p.write
        clock, drain = self._clock, self._drain

        def read(_uc: int, offset: int, size: int, _data: int) -> int:
            try:
                if clock.undrained:  # what the USARTs did in C comes first
                    drain()
                return peripheral_read(offset, size)
            except BaseException as exc:  # stops the CPU; cpu.run raises it
                fail(exc)
                return 0

        def write(_uc: int, offset: int, size: int, value: int, _data: int) -> None:
            try:
                if clock.undrained:
                    drain()
                peripheral_write(offset, size, value)
            except BaseException as exc:
                fail(exc)

        fast = getattr(p, "fast", None)
        if fast is not None:
            fast.counter = self._clock
        self.cpu.map_io(p.base, p.size, read, write, fast)

    # -- time --------------------------------------------------------------------------------

    @property
    def hz(self) -> float:
        """Instructions per second: the processor clock (HCLK)."""
        return self._clock.hz

    def _rebase(self) -> None:
        c = self._clock
        c.t0 = self.now()
        c.c0 = c.count

    def _skip(self, seconds: float) -> None:
        self._clock.t0 += seconds

    def stall(self, seconds: float) -> None:
        """The CPU stops for ``seconds`` (the flash is busy) while time goes on."""
        self._skip(seconds)
        self.stalled_s += seconds
        self.cpu.stop_soon()

    def _event_scheduled(self, t: float) -> None:
        if self.cpu.running:  # cpu.stop_soon, inline: an event is scheduled at every byte
            c = self._clock
            cycles = math.ceil((t - lib.mcu_now(c)) * c.hz - 1e-6)
            limit = c.count + (cycles if cycles > 0 else 0)
            if limit < c.limit:
                c.limit = limit
            if t < c.stop_at:
                c.stop_at = t

    def _drain(self) -> None:
        """The USARTs hand on what their shift registers did in C."""
        self._clock.undrained = 0
        for u in self._usarts:
            u.drain()

    def time_usarts_in_python(self) -> None:
        """The USARTs' frames timed by their models' events rather than in C (a test
        compares the two)."""
        self._clock.n_timed = 0
        for u in self._usarts:
            u.time_in_c(None)

    def run_events(self, now: float) -> None:
        """Run every event due by ``now``: the ones timed in C first (the USARTs' frames),
        then the scheduler's."""
        clock = self._clock
        while lib.mcu_timed_run(clock, now):
            self._drain()
        if clock.undrained:
            self._drain()
        self.scheduler.run_due(now)

    def _next_event(self) -> float | None:
        """When the next event is due, the ones timed in C included."""
        t = self.scheduler.next_time()
        timed = lib.mcu_timed_next(self._clock)
        return timed if timed >= 0.0 and (t is None or timed <= t) else t

    def _clock_gates_changed(self) -> None:
        self.usart1.clock_changed()
        self.usart3.clock_changed()

    def _clocks_changed(self, clocks: Clocks) -> None:
        self._rebase()
        self.flash.check_clock(clocks.sysclk)
        self._clock.hz = clocks.hclk
        self.systick.set_hclk(clocks.hclk)
        for u in self._usarts:
            u.rate_changed()

    # -- memory --------------------------------------------------------------------------------

    def load(self, address: int, data: bytes) -> None:
        """Put ``data`` in flash (or RAM) at ``address``, as a programmer would."""
        end = address + len(data)
        in_flash = FLASH_BASE <= address and end <= FLASH_BASE + FLASH_SIZE
        in_ram = RAM_BASE <= address and end <= RAM_BASE + RAM_SIZE
        if not (in_flash or in_ram):
            raise McuFault(f"{len(data)} bytes at 0x{address:08X} do not fit the flash or RAM")
        if in_ram:
            self.cpu.uc.mem_write(address, data)
            self.cpu.uc.ctl_remove_cache(address, end)  # code run from there before
        if in_flash:
            self._write_flash(address, data)
            wfi, after = unmasking_sites(data, address)
            self.cpu.watch(wfi, after)

    def _write_flash(self, address: int, data: bytes) -> None:
        """Put ``data`` in the flash at ``address`` and drop the code translated from it."""
        ctypes.memmove(ctypes.addressof(self._flash_bytes) + address - FLASH_BASE, data, len(data))
        self.cpu.uc.ctl_remove_cache(address, address + len(data))

    def read(self, address: int, size: int) -> bytes:
        return bytes(self.cpu.uc.mem_read(address, size))

    def _fetch_from_ram(
        self, uc: Uc, access: int, address: int, size: int, value: int, _data: object
    ) -> bool:
        """The CPU runs code from RAM (as the chip can): RAM becomes executable and the
        fetch is made again."""
        if RAM_BASE <= address < RAM_BASE + RAM_SIZE:
            uc.mem_protect(RAM_BASE, RAM_SIZE, UC_PROT_ALL)
            return True
        return False

    def _flash_write(
        self, uc: Uc, access: int, address: int, size: int, value: int, _data: object
    ) -> bool:
        if FLASH_BASE <= address < FLASH_BASE + FLASH_SIZE:
            self.flash.program(address, size, value)
            return True
        return False

    # -- resets ----------------------------------------------------------------------------------

    def _software_reset(self) -> None:
        self._reset_request = RESET_SOFTWARE
        self.cpu.stop_soon()

    def _watchdog_reset(self) -> None:
        self._reset_request = RESET_WATCHDOG
        self.cpu.stop_soon()

    def reset(self, kind: str = RESET_PIN) -> None:
        """Reset the chip: every peripheral to its reset values, the clock back to the HSI,
        RAM kept (as on the chip), then ``on_reset(kind)`` places the CPU."""
        self._rebase()
        self.resets.append((self.now(), kind))
        for p in self.peripherals:
            p.reset()
        self.rcc.note_reset(
            {
                RESET_SOFTWARE: rcc_mod.CSR_SFT,
                RESET_WATCHDOG: rcc_mod.CSR_IWDG,
                RESET_PIN: rcc_mod.CSR_PIN,
                RESET_POWER: rcc_mod.CSR_POR,
            }[kind]
        )
        self.cpu.sleeping = False
        if self.on_reset is not None:
            self.on_reset(kind)

    def boot(self, vector_table: int) -> None:
        """Start the CPU from the vector table at ``vector_table`` (its stack pointer and
        reset handler), VTOR left at its reset value 0, as a jump from a bootloader does."""
        sp = self.cpu.read32(vector_table)
        pc = self.cpu.read32(vector_table + 4)
        self.cpu.boot(sp, pc)

    # -- running ---------------------------------------------------------------------------------

    def run_until(self, t_end: float) -> None:
        """Run the chip until its time reaches ``t_end`` (seconds)."""
        cpu = self.cpu
        scheduler = self.scheduler
        any_pending = functools.partial(lib.mcu_nvic_any_pending, self.nvic.c)
        self._t_end = t_end
        while True:
            now = self.now()
            self.run_events(now)
            if self._reset_request is not None:
                kind, self._reset_request = self._reset_request, None
                self.reset(kind)
                continue
            if now >= t_end:
                return
            if any_pending():
                cpu.take_exceptions()
            next_event = scheduler.next_time()
            stop = t_end if next_event is None or next_event > t_end else next_event
            if cpu.sleeping and not cpu.wake_if_due():
                timed = lib.mcu_timed_next(self._clock)
                if 0.0 <= timed < stop:
                    stop = timed
                self._skip(max(stop - now, 0.0))  # asleep: time jumps to the next event
                continue
            cycles = math.ceil((stop - now) * self.hz - 1e-6)
            cpu.run(max(cycles, 1), until=stop)

    def _sleep_in_run(self) -> bool:
        """The CPU sleeps (WFI) inside a run: as :meth:`run_until` would, time jumps from
        event to event until one wakes the CPU, without leaving the run; then the run's
        limit is set to the next event. False (stop, and sleep in run_until) if no event
        before the run's end wakes it, or one asks for a reset."""
        cpu, scheduler, t_end = self.cpu, self.scheduler, self._t_end
        if self._clock.undrained:  # a TC timed in C stopped the sleep in C: handed on now
            self._drain()
        while True:
            next_event = self._next_event()
            if next_event is None or next_event > t_end:
                return False
            now = self.now()
            if next_event > now:
                self._skip(next_event - now)
            self.run_events(self.now())
            if self._reset_request is not None:
                return False
            if cpu.wake_if_due():
                break
        now = self.now()
        next_event = scheduler.next_time()
        stop = t_end if next_event is None or next_event > t_end else next_event
        cpu.counter.limit = cpu.counter.count + max(math.ceil((stop - now) * self.hz - 1e-6), 1)
        cpu.counter.stop_at = stop
        lib.mcu_timed_plan(cpu.counter)
        return True

    def irq_pending(self, irq: int) -> bool:
        return bool(self.nvic.pending >> (SYSTEM_EXCEPTIONS + irq) & 1)
