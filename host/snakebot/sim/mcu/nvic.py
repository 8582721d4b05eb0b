"""The Cortex-M3's system control space (ARMv7-M architecture manual, B3.2 and B3.4): the
NVIC (enables, pending and active bits, priorities) and the SCB registers the firmware
uses (CPUID, ICSR, VTOR, AIRCR with PRIGROUP and SYSRESETREQ, SCR, CCR, SHPR1-3).

Exception state lives here; :mod:`snakebot.sim.mcu.cpu` does the entry and return. The
STM32F103 implements 4 priority bits (the upper nibble of each priority byte; the lower
nibble reads as zero) and 60 interrupt lines. Device interrupts are level-sensitive: a
peripheral sets its line (:meth:`Nvic.set_line`), a line that is high pends its interrupt,
and a line still high when its handler returns pends it again. Preemption compares group
priorities (the bits above PRIGROUP); among pending exceptions the lowest priority number
wins, then the lowest exception number. PRIMASK raises the execution priority to 0.
"""

from __future__ import annotations

from collections.abc import Callable

from snakebot.core import ffi, lib
from snakebot.sim.mcu.regs import Peripheral
from snakebot.sim.mcu.systick import SysTick

BASE = 0xE000E000
IRQ_COUNT = 60
SYSTEM_EXCEPTIONS = 16
NMI, HARDFAULT, SVCALL, PENDSV, SYSTICK = 2, 3, 11, 14, 15
PRIO_BITS = 4
PRIO_MASK = (0xFF << (8 - PRIO_BITS)) & 0xFF
NO_PRIORITY = 256  # thread mode with nothing active

CPUID_VALUE = 0x411FC231  # Cortex-M3 r1p1, as in the STM32F103
ICTR, SYST_FIRST = 0x004, lib.MCU_SCS_SYSTICK
SYST_LAST = SYST_FIRST + 0xF
ISER, ICER, ISPR, ICPR, IABR = 0x100, 0x180, 0x200, 0x280, 0x300
IPR = IABR + 0x100  # the priority bytes
CPUID, ICSR, VTOR, AIRCR, SCR, CCR, SHPR1, SHCSR = (
    0xD00,
    0xD04,
    0xD08,
    0xD0C,
    0xD10,
    0xD14,
    0xD18,
    0xD24,
)
VECTKEY = 0x05FA
AIRCR_VECTRESET, AIRCR_VECTCLRACTIVE, AIRCR_SYSRESETREQ = 1 << 0, 1 << 1, 1 << 2
ICSR_PENDSTCLR, ICSR_PENDSTSET, ICSR_PENDSVCLR, ICSR_PENDSVSET = 1 << 25, 1 << 26, 1 << 27, 1 << 28
ICSR_NMIPENDSET = 1 << 31
VTOR_MASK = 0x3FFF_FF80
CCR_RESET = 0x0000_0200  # STKALIGN: 8-byte aligned exception frames
WORDS = (IRQ_COUNT + 31) // 32
MASK64 = (1 << 64) - 1
ALWAYS_ENABLED = sum(1 << e for e in (NMI, HARDFAULT, SVCALL, PENDSV, SYSTICK))
"""The system exceptions that have no enable bit here (their handlers are always on)."""


class Nvic(Peripheral):
    """The system control space, SysTick included (``systick``, at 0xE000E010).

    The exception state lives in :attr:`c` (an ``mcu_nvic``, see mcu_nvic.h), where the
    CPU's hooks take and return from exceptions without a Python call; whenever an
    exception may have become takeable (pended, enabled, its priority raised) the CPU
    attached there stops to look. ``on_reset()`` is called for SYSRESETREQ."""

    name = "SCS"
    size = 0x1000

    def __init__(
        self,
        systick: SysTick | None = None,
        *,
        on_reset: Callable[[], None] | None = None,
        strict: bool = True,
    ) -> None:
        super().__init__(BASE, strict=strict)
        self.systick = systick
        self.on_reset = on_reset or (lambda: None)
        self.c = ffi.new("mcu_nvic *")
        self.c.always = ALWAYS_ENABLED
        self.fast = ffi.new("mcu_fast_io *")  # SysTick's CSR and CVR read in C (mcu_count.h)
        self.fast.kind = lib.MCU_IO_SCS
        self.reset()

    def reset(self) -> None:
        c = self.c
        c.pending = [0, 0]
        c.enabled = 0
        c.lines = 0
        c.depth = 0
        c.entries = 0
        self.vtor = 0
        self.ipr = bytearray(IRQ_COUNT)
        self.shpr = bytearray(12)  # exceptions 4..15
        self.prigroup = 0
        self.ccr = CCR_RESET
        self._regroup()

    # -- exception state (in C) -------------------------------------------------------------

    @property
    def pending(self) -> int:
        """Bit per exception number."""
        words = self.c.pending
        return int(words[0]) | int(words[1]) << 64

    @pending.setter
    def pending(self, bits: int) -> None:
        self.c.pending = [bits & MASK64, bits >> 64 & MASK64]

    @property
    def enabled(self) -> int:
        """Bit per device interrupt."""
        return int(self.c.enabled)

    @enabled.setter
    def enabled(self, bits: int) -> None:
        self.c.enabled = bits & MASK64

    @property
    def lines(self) -> int:
        """Bit per device interrupt: its peripheral's line is high."""
        return int(self.c.lines)

    @property
    def active(self) -> list[int]:
        """Exception numbers, outermost first."""
        return list(self.c.active[0 : self.c.depth])

    @property
    def vtor(self) -> int:
        return int(self.c.vtor)

    @vtor.setter
    def vtor(self, value: int) -> None:
        self.c.vtor = value

    @property
    def entries(self) -> int:
        """Exceptions taken."""
        return int(self.c.entries)

    def _regroup(self) -> None:
        """Work out every exception's priority and group again (after a write to them)."""
        exceptions = range(SYSTEM_EXCEPTIONS + IRQ_COUNT)
        priorities = [self.priority(e) for e in exceptions]
        self.c.priority = priorities
        self.c.group = [self.group(p) for p in priorities]
        lib.mcu_nvic_rerun(self.c)

    def priority(self, exception: int) -> int:
        if exception == 1:
            return -3
        if exception == NMI:
            return -2
        if exception == HARDFAULT:
            return -1
        if exception < SYSTEM_EXCEPTIONS:
            return self.shpr[exception - 4]
        return self.ipr[exception - SYSTEM_EXCEPTIONS]

    def group(self, priority: int) -> int:
        """The group (preemption) part of a priority under PRIGROUP."""
        if priority < 0:
            return priority
        return priority & ~((2 << self.prigroup) - 1) & 0xFF

    def execution_priority(self, primask: bool) -> int:
        running = int(self.c.running)
        return min(running, 0) if primask else running

    def best_pending(self) -> int | None:
        """The pending, enabled exception that would be taken first, if any."""
        best = lib.mcu_nvic_best(self.c)
        return None if best < 0 else best

    def takeable(self, primask: bool, best: int | None = None) -> int | None:
        """The exception to take now, if one may preempt what runs (``best``: the
        :meth:`best_pending` the caller already has)."""
        exception = lib.mcu_nvic_takeable(self.c, primask, -1 if best is None else best)
        return None if exception < 0 else exception

    def pend(self, exception: int) -> None:
        lib.mcu_nvic_pend(self.c, exception)

    def set_line(self, irq: int, level: bool) -> None:
        """A peripheral's interrupt line: high pends the interrupt (unless it is active)."""
        lib.mcu_nvic_set_line(self.c, irq, level)

    def activate(self, exception: int) -> None:
        """The CPU enters ``exception``'s handler."""
        lib.mcu_nvic_activate(self.c, exception)

    def deactivate(self) -> int:
        """The CPU returns from the innermost handler; returns its exception number."""
        exception = lib.mcu_nvic_deactivate(self.c)
        if exception < 0:
            raise IndexError("no exception is active")
        return exception

    # -- registers ----------------------------------------------------------------------------

    def read(self, offset: int, size: int) -> int:
        if SYST_FIRST <= offset <= SYST_LAST and self.systick is not None:
            return self.systick.read(offset - SYST_FIRST, size)
        if IPR <= offset < IPR + IRQ_COUNT:
            return int.from_bytes(self.ipr[offset - IPR : offset - IPR + size], "little")
        if SHPR1 <= offset < SHPR1 + 12:
            start = offset - SHPR1
            return int.from_bytes(self.shpr[start : start + size], "little")
        if not self.word_only(offset, size, None):
            return 0
        for base, bits in ((ISER, self.enabled), (ICER, self.enabled)):
            if base <= offset < base + 32:
                return self._word(bits, offset - base)
        if ISPR <= offset < ISPR + 32 or ICPR <= offset < ICPR + 32:
            return self._word(self.pending >> SYSTEM_EXCEPTIONS, offset & 0x1F)
        if IABR <= offset < IABR + 32:
            active = sum(1 << (e - SYSTEM_EXCEPTIONS) for e in self.active if e >= 16)
            return self._word(active, offset - IABR)
        if offset == ICTR:
            return (IRQ_COUNT - 1) // 32
        if offset == CPUID:
            return CPUID_VALUE
        if offset == ICSR:
            return self._icsr()
        if offset == VTOR:
            return self.vtor
        if offset == AIRCR:
            return 0xFA05_0000 | self.prigroup << 8
        if offset == SCR:
            return 0
        if offset == CCR:
            return self.ccr
        return self.unknown(offset, size, None)

    @staticmethod
    def _word(bits: int, byte_offset: int) -> int:
        n = byte_offset // 4
        return (bits >> (32 * n)) & 0xFFFF_FFFF if n < WORDS else 0

    def _icsr(self) -> int:
        value = self.active[-1] if self.active else 0
        if len(self.active) <= 1:
            value |= 1 << 11  # RETTOBASE
        pending = self.best_pending()
        if pending is not None:
            value |= (pending & 0x1FF) << 12
        if self.pending >> SYSTEM_EXCEPTIONS:
            value |= 1 << 22  # ISRPENDING
        if self.pending >> SYSTICK & 1:
            value |= ICSR_PENDSTSET
        if self.pending >> PENDSV & 1:
            value |= ICSR_PENDSVSET
        return value

    def write(self, offset: int, size: int, value: int) -> None:
        if SYST_FIRST <= offset <= SYST_LAST and self.systick is not None:
            self.systick.write(offset - SYST_FIRST, size, value)
            return
        if IPR <= offset < IPR + IRQ_COUNT:
            for i in range(size):
                if offset - IPR + i < IRQ_COUNT:
                    self.ipr[offset - IPR + i] = (value >> (8 * i)) & PRIO_MASK
            self._regroup()
            lib.mcu_nvic_changed(self.c)
            return
        if SHPR1 <= offset < SHPR1 + 12:
            for i in range(size):
                self.shpr[offset - SHPR1 + i] = (value >> (8 * i)) & PRIO_MASK
            self._regroup()
            lib.mcu_nvic_changed(self.c)
            return
        if not self.word_only(offset, size, value):
            return
        n = (offset & 0x1F) // 4
        mask = (value & 0xFFFF_FFFF) << (32 * n) if n < WORDS else 0
        mask &= (1 << IRQ_COUNT) - 1
        if ISER <= offset < ISER + 32:
            self.enabled |= mask
            lib.mcu_nvic_changed(self.c)
        elif ICER <= offset < ICER + 32:
            self.enabled &= ~mask
        elif ISPR <= offset < ISPR + 32:
            self.pending |= mask << SYSTEM_EXCEPTIONS
            lib.mcu_nvic_changed(self.c)
        elif ICPR <= offset < ICPR + 32:
            self.pending &= ~(mask << SYSTEM_EXCEPTIONS)
        elif offset == ICSR:
            self._write_icsr(value)
        elif offset == VTOR:
            self.vtor = value & VTOR_MASK
        elif offset == AIRCR:
            self._write_aircr(value)
        elif offset == SCR:
            if value:
                self.unknown(offset, size, value)  # sleep-on-exit, deep sleep, SEVONPEND
        elif offset == CCR:
            if value != self.ccr:
                self.unknown(offset, size, value)
        else:
            self.unknown(offset, size, value)

    def _write_icsr(self, value: int) -> None:
        if value & ICSR_PENDSTCLR:
            self.pending &= ~(1 << SYSTICK)
        if value & ICSR_PENDSVCLR:
            self.pending &= ~(1 << PENDSV)
        if value & ICSR_PENDSTSET:
            self.pend(SYSTICK)
        if value & ICSR_PENDSVSET:
            self.pend(PENDSV)
        if value & ICSR_NMIPENDSET:
            self.unknown(ICSR, 4, value)

    def _write_aircr(self, value: int) -> None:
        if value >> 16 != VECTKEY:
            return  # without the key the write is ignored
        if value & (AIRCR_VECTRESET | AIRCR_VECTCLRACTIVE):
            self.unknown(AIRCR, 4, value)  # debug-only resets
        self.prigroup = (value >> 8) & 7
        self._regroup()
        if value & AIRCR_SYSRESETREQ:
            self.on_reset()
