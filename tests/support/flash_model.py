"""A register model of the STM32F1 flash controller (FPEC, PM0075) and of the flash it
programs, for host builds of the flash driver and the stores on it: QEMU has no flash
controller, so this is where their logic is proven. The model behaves like the chip where
the driver depends on it: the controller starts locked and opens only to KEY1 then KEY2,
BSY stays set for a while after each operation, programming a half-word that is not erased
sets PGERR and changes nothing, protected pages set WRPRTERR. :class:`PowerCutModel` cuts
the power during a chosen operation."""

from __future__ import annotations

import random

FLASH_R = 0x40022000
ACR, KEYR, SR, CR, AR = (FLASH_R + o for o in (0x00, 0x04, 0x0C, 0x10, 0x14))
KEY1, KEY2 = 0x45670123, 0xCDEF89AB
SR_BSY, SR_PGERR, SR_WRPRTERR, SR_EOP = 1 << 0, 1 << 2, 1 << 4, 1 << 5
CR_PG, CR_PER, CR_STRT, CR_LOCK = 1 << 0, 1 << 1, 1 << 6, 1 << 7

BASE = 0x08078000  # where the models put flash unless told (a page-aligned CM-530 address)
PAGE = 2048
PAGES = 4


class FlashModel:
    """The FPEC's registers and PAGES pages of flash at ``base`` (BASE unless given)."""

    plain_reads = True
    """:meth:`read16` of flash has no side effect, so the host HAL reads ``mem`` itself
    (firmware_support.RegisterModels.serve); a subclass whose reads do more says False."""

    def __init__(self, busy_reads: int = 3, base: int = BASE) -> None:
        self.base = base
        self.mem = bytearray(b"\xa5" * (PAGE * PAGES))  # old content, not erased
        self.cr = CR_LOCK
        self.sr = 0
        self.ar = 0
        self.key_step = 0
        self.key_fault = False  # a wrong key locks the FPEC until reset
        self.busy_reads = busy_reads
        self.busy_left = 0
        self.stuck_busy = False
        self.protected_pages: set[int] = set()
        self.weak_cells: set[int] = set()  # half-word offsets that never take a value
        self.unexpected: list[str] = []
        self.writes = 0  # register and flash writes, for "touched nothing" checks

    # -- helpers --------------------------------------------------------------------------
    def start(self) -> None:
        self.busy_left = self.busy_reads

    def locked(self) -> bool:
        return bool(self.cr & CR_LOCK)

    def in_flash(self, addr: int) -> bool:
        return self.base <= addr < self.base + len(self.mem)

    # -- bus ----------------------------------------------------------------------------
    def read32(self, addr: int) -> int:
        if addr == SR:
            if self.stuck_busy or self.busy_left > 0:
                self.busy_left = max(0, self.busy_left - 1)
                return self.sr | SR_BSY
            if self.sr & SR_BSY:
                self.sr &= ~SR_BSY
            return self.sr
        if addr == CR:
            return self.cr
        if addr == AR:
            return self.ar
        self.unexpected.append(f"read32 {addr:#x}")
        return 0

    def write32(self, addr: int, value: int) -> None:
        self.writes += 1
        if addr == KEYR:
            if self.key_fault:
                return
            if self.key_step == 0 and value == KEY1:
                self.key_step = 1
            elif self.key_step == 1 and value == KEY2:
                self.key_step = 0
                self.cr &= ~CR_LOCK
            else:
                self.key_fault = True
                self.cr |= CR_LOCK
            return
        if addr == SR:
            self.sr &= ~(value & (SR_PGERR | SR_WRPRTERR | SR_EOP))
            return
        if addr == AR:
            self.ar = value
            return
        if addr == CR:
            if self.locked():
                return  # CR is write-protected while locked
            if self.busy_left:
                self.unexpected.append("CR written while busy")
            self.cr = value & (CR_PG | CR_PER | CR_STRT | CR_LOCK)
            if self.cr & CR_STRT:
                self.cr &= ~CR_STRT
                if self.cr & CR_PER:
                    self.erase(self.ar)
            return
        self.unexpected.append(f"write32 {addr:#x}")

    def erase(self, addr: int) -> None:
        self.start()
        if not self.in_flash(addr):
            self.unexpected.append(f"erase outside the store: {addr:#x}")
            return
        page = (addr - self.base) // PAGE
        if page in self.protected_pages:
            self.sr |= SR_WRPRTERR
            return
        self.mem[page * PAGE : (page + 1) * PAGE] = b"\xff" * PAGE
        self.sr |= SR_EOP

    def read16(self, addr: int) -> int:
        if not self.in_flash(addr) or addr & 1:
            self.unexpected.append(f"read16 {addr:#x}")
            return 0
        off = addr - self.base
        return self.mem[off] | self.mem[off + 1] << 8

    def write16(self, addr: int, value: int) -> None:
        self.writes += 1
        if not self.in_flash(addr) or addr & 1:
            self.unexpected.append(f"write16 {addr:#x}")
            return
        if not (self.cr & CR_PG) or self.locked():
            self.unexpected.append(f"flash written without PG at {addr:#x}")
            return
        self.start()
        off = addr - self.base
        if off // PAGE in self.protected_pages:
            self.sr |= SR_WRPRTERR
            return
        if self.read16(addr) != 0xFFFF and value != 0:
            self.sr |= SR_PGERR
            return
        if off in self.weak_cells:
            return
        self.mem[off] = value & 0xFF
        self.mem[off + 1] = value >> 8
        self.sr |= SR_EOP


class QemuLikeModel(FlashModel):
    """QEMU's stm32vldiscovery: the flash interface is an unimplemented device (reads 0,
    writes ignored) and flash is ROM."""

    def read32(self, addr: int) -> int:
        return 0

    def write32(self, addr: int, value: int) -> None:
        self.writes += 1

    def write16(self, addr: int, value: int) -> None:
        self.writes += 1


class PowerCutModel(FlashModel):
    """A FlashModel whose power fails during its ``cut_at``-th flash operation (page erase
    or half-word program, counted from 0): that operation is left torn (an erase sets a
    random part of the page's bits back to 1, a program clears a random part of the bits
    it should), and nothing changes flash after it. ``cut_at=None`` never cuts; ``ops``
    counts the operations started, so a run without a cut tells how many there are."""

    def __init__(
        self, mem: bytes | None = None, cut_at: int | None = None, seed: int = 0, base: int = BASE
    ):
        super().__init__(busy_reads=1, base=base)
        if mem is not None:
            self.mem[:] = mem
        self.cut_at = cut_at
        self.ops = 0
        self.dead = False
        self.rng = random.Random(seed)

    def _step(self) -> str:
        """Start one operation: "run" it, "tear" it (the cut), or "skip" it (after)."""
        if self.dead:
            return "skip"
        self.ops += 1
        if self.ops - 1 == self.cut_at:
            self.dead = True
            return "tear"
        return "run"

    def erase(self, addr: int) -> None:
        step = self._step()
        if step == "run":
            super().erase(addr)
        elif step == "tear" and self.in_flash(addr):
            page = (addr - self.base) // PAGE
            for i in range(page * PAGE, (page + 1) * PAGE):
                self.mem[i] |= self.rng.getrandbits(8)

    def write16(self, addr: int, value: int) -> None:
        step = self._step()
        if step == "run":
            super().write16(addr, value)
        elif step == "tear" and self.in_flash(addr):
            off = addr - self.base
            keep = value | self.rng.getrandbits(16)
            self.mem[off] &= keep & 0xFF
            self.mem[off + 1] &= keep >> 8
