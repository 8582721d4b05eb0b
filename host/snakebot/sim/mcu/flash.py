"""The flash memory interface (RM0008 section 3.3, PM0075) and what it does to the flash.

Modelled: ACR (wait states, prefetch; the prefetch status follows the enable), the unlock
sequence (KEY1 then KEY2; anything else locks the controller until the next reset), page
erase (PER, AR, STRT), half-word programming (PG, then a half-word write to the flash:
PGERR if the cell is not erased and the value is not zero), mass erase is refused (it
would erase the bootloader), the status flags (BSY, PGERR, WRPRTERR, EOP; written 1 to
clear) and LOCK. While the controller erases or programs the CPU, which fetches its code
from this flash, stalls: erase and program take their datasheet times (``stall``), after
which BSY is already clear. The rules the hardware imposes are checked: a write to the
flash without PG, a program of anything but a half-word, and a system clock above what
the wait states allow are faults. The ROBOTIS bootloader's pages (below the application
base) are write-protected, as the bootloader protects itself.
"""

from __future__ import annotations

from collections.abc import Callable

from snakebot.facts.memory import FLASH_BASE
from snakebot.sim.mcu.errors import McuFault
from snakebot.sim.mcu.regs import Peripheral

BASE = 0x40022000

ACR, KEYR, OPTKEYR, SR, CR, AR, RESERVED, OBR, WRPR = range(0, 0x24, 4)
KEY1, KEY2 = 0x45670123, 0xCDEF89AB
SR_BSY, SR_PGERR, SR_WRPRTERR, SR_EOP = 1 << 0, 1 << 2, 1 << 4, 1 << 5
CR_PG, CR_PER, CR_MER, CR_STRT, CR_LOCK, CR_EOPIE = (1 << n for n in (0, 1, 2, 6, 7, 12))
CR_ERRIE = CR_EOPIE >> 2  # bit 10
ACR_LATENCY, ACR_HLFCYA, ACR_PRFTBE, ACR_PRFTBS = 0x7, 1 << 3, 1 << 4, 1 << 5
ACR_RESET = 0x30  # prefetch on, and its status

PAGE_ERASE_S = 20e-3  # datasheet tERASE, typical
HALFWORD_PROGRAM_S = 52.5e-6  # datasheet tPROG, typical
MAX_HZ_BY_LATENCY = {0: 24_000_000, 1: 48_000_000, 2: 72_000_000}


class FlashInterface(Peripheral):
    """The controller of a flash of ``size`` bytes at 0x08000000 in pages of ``page``
    bytes, pages below ``protected_below`` write-protected. ``read``/``write`` reach the
    flash's bytes; ``stall(seconds)`` holds the CPU while an operation runs."""

    name = "FLASH"

    def __init__(
        self,
        *,
        size: int,
        page: int,
        protected_below: int,
        read: Callable[[int, int], bytes],
        write: Callable[[int, bytes], None],
        stall: Callable[[float], None],
        strict: bool = True,
    ) -> None:
        super().__init__(BASE, strict=strict)
        self.flash_size = size
        self.page = page
        self.protected_below = protected_below
        self._read = read
        self._write = write
        self._stall = stall
        self.erases = 0
        self.programs = 0
        self.sysclk = 8_000_000
        self.reset()

    def reset(self) -> None:
        self.acr = ACR_RESET
        self.sr = 0
        self.cr = CR_LOCK
        self.ar = 0
        self._key_step = 0
        self._locked_out = False

    def check_clock(self, sysclk_hz: int) -> None:
        """Note the system clock ``sysclk_hz``. A SYSCLK above what the wait states allow
        reads wrong instructions on the chip: here it is a fault, named."""
        self.sysclk = sysclk_hz
        latency = self.acr & ACR_LATENCY
        limit = MAX_HZ_BY_LATENCY.get(latency, MAX_HZ_BY_LATENCY[2])
        if sysclk_hz > limit:
            raise McuFault(
                f"SYSCLK {sysclk_hz / 1e6:g} MHz with {latency} flash wait state(s) (at most "
                f"{limit / 1e6:g} MHz): raise FLASH_ACR LATENCY before the clock"
            )

    def read(self, offset: int, size: int) -> int:
        if not self.word_only(offset, size, None):
            return 0
        if offset == ACR:
            prefetch_on = ACR_PRFTBS if self.acr & ACR_PRFTBE else 0
            return (self.acr & ~ACR_PRFTBS) | prefetch_on
        if offset == SR:
            return self.sr
        if offset == CR:
            return self.cr
        if offset == AR:
            return self.ar
        if offset == WRPR:
            return 0xFFFF_FFFF
        if offset == OBR:
            return 0x03FF_FFFC  # option bytes as shipped: no read protection
        return self.unknown(offset, size, None)

    def write(self, offset: int, size: int, value: int) -> None:
        if not self.word_only(offset, size, value):
            return
        if offset == ACR:
            self.acr = value & (ACR_LATENCY | ACR_HLFCYA | ACR_PRFTBE)
            self.check_clock(self.sysclk)
        elif offset == KEYR:
            self._key(value)
        elif offset == SR:
            self.sr &= ~(value & (SR_PGERR | SR_WRPRTERR | SR_EOP))
        elif offset == CR:
            self._write_cr(value)
        elif offset == AR:
            if not self.cr & CR_LOCK:
                self.ar = value
        else:
            self.unknown(offset, size, value)

    def _key(self, value: int) -> None:
        if self._locked_out or not self.cr & CR_LOCK:
            self._locked_out = True  # a key while unlocked, or after a wrong one: locked
            self.cr |= CR_LOCK
            return
        if self._key_step == 0 and value == KEY1:
            self._key_step = 1
        elif self._key_step == 1 and value == KEY2:
            self._key_step = 0
            self.cr &= ~CR_LOCK
        else:
            self._locked_out = True

    def _write_cr(self, value: int) -> None:
        if self.cr & CR_LOCK:
            return  # locked: only the key sequence opens it
        if value & (CR_EOPIE | CR_ERRIE | 0x30):  # interrupts, option bytes
            self.unknown(CR, 4, value)
            return
        if value & CR_MER:
            raise McuFault("FLASH: mass erase would erase the ROBOTIS bootloader: erase pages")
        self.cr = value & (CR_PG | CR_PER | CR_LOCK)
        if self.cr & CR_LOCK:
            self._key_step = 0
        if value & CR_STRT:
            if not self.cr & CR_PER:
                raise McuFault("FLASH: STRT without PER (page erase) or MER")
            self._erase_page(self.ar)

    def _erase_page(self, address: int) -> None:
        start = address - FLASH_BASE
        start -= start % self.page
        if not 0 <= start < self.flash_size:
            raise McuFault(f"FLASH: page erase at 0x{address:08X} is outside the flash")
        self._stall(PAGE_ERASE_S)
        if FLASH_BASE + start < self.protected_below:
            self.sr |= SR_WRPRTERR
            return
        self._write(FLASH_BASE + start, b"\xff" * self.page)
        self.erases += 1
        self.sr |= SR_EOP

    def program(self, address: int, size: int, value: int) -> None:
        """The CPU wrote ``value`` (``size`` bytes) to the flash at ``address``."""
        if not self.cr & CR_PG:
            raise McuFault(
                f"write of 0x{value:X} to flash at 0x{address:08X} without FLASH_CR PG: "
                "the flash takes writes only while programming"
            )
        if size != 2 or address % 2:
            raise McuFault(
                f"{size}-byte write to flash at 0x{address:08X}: the flash is programmed "
                "one aligned half-word at a time"
            )
        self._stall(HALFWORD_PROGRAM_S)
        if address < self.protected_below:
            self.sr |= SR_WRPRTERR
            return
        old = int.from_bytes(self._read(address, 2), "little")
        if old != 0xFFFF and value != 0:
            self.sr |= SR_PGERR
            return
        self._write(address, value.to_bytes(2, "little"))
        self.programs += 1
        self.sr |= SR_EOP
