"""The Cortex-M3 core: unicorn's ARMv7-M CPU, with the exception model done here.

Unicorn (the QEMU CPU core as a library) executes the instructions; it has no NVIC, so
exception entry and return are done by this module as the ARMv7-M architecture manual
describes (B1.5.6 and B1.5.8): on entry the eight-word frame (r0-r3, r12, lr, the return
address, xPSR) is pushed on the main stack, 8-byte aligned (bit 9 of the stacked xPSR
records the padding), LR gets EXC_RETURN and PC the handler from the vector table at
VTOR; a branch to EXC_RETURN (unicorn reports it as its exception-exit interrupt) pops the
frame. Only the main stack is modelled (the firmware never uses the process stack: an
EXC_RETURN asking for it is a fault). Entry, return and the choice of what to take are C
(``snakebot._core``'s mcu_nvic and mcu_exception_*): the return and a tail-chained entry
run inside unicorn's interrupt hook, an entry after an unmask inside the counter's hook,
without a Python call.

Time: a native instruction counter (``snakebot._core``'s ``mcu_count_instruction``, a
unicorn code hook) counts every executed instruction and stops the CPU at a limit, so
the machine knows the exact instruction count at every register access and runs the CPU
exactly up to the next peripheral event. One instruction counts one cycle. Events timed
in C (the USARTs' frames, mcu_usart.h) run from the same hook at their instruction, and a
``wfi`` jumps to them, without stopping the CPU.

Interrupts are looked at whenever the CPU stops: at an event, after a register write that
pended or enabled one (the write lowers the limit so the CPU stops after it), and after
every instruction that may unmask them (``cpsie i``, ``msr primask``), which are found in
the image when it is loaded: there a pending exception is taken from the hook on the next
instruction, before it runs, without stopping the CPU. ``wfi`` stops the CPU until an
exception that could preempt is pending.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Iterable

from snakebot.extras import require

require("unicorn", "the emulated CM-530 (snakebot.sim.mcu)")

from unicorn import (  # noqa: E402
    UC_ARCH_ARM,
    UC_HOOK_CODE,
    UC_HOOK_INTR,
    UC_HOOK_MEM_FETCH_PROT,
    UC_HOOK_MEM_WRITE_PROT,
    UC_MODE_MCLASS,
    UC_MODE_THUMB,
    UC_PROT_ALL,
    UC_PROT_EXEC,
    UC_PROT_READ,
    UC_PROT_WRITE,
    Uc,
    UcError,
)
from unicorn import arm_const as arm  # noqa: E402
from unicorn.unicorn_py3.unicorn import (  # noqa: E402
    MMIO_READ_CFUNC,
    MMIO_WRITE_CFUNC,
    uclib,
)

from snakebot.core import ffi, lib  # noqa: E402
from snakebot.sim.mcu.errors import McuFault  # noqa: E402
from snakebot.sim.mcu.nvic import Nvic  # noqa: E402

__all__ = ["Cpu", "Uc", "unmasking_sites", "UC_HOOK_MEM_WRITE_PROT", "UC_PROT_ALL"]
__all__ += ["UC_PROT_EXEC", "UC_PROT_READ", "UC_PROT_WRITE", "UC_HOOK_MEM_FETCH_PROT"]

FRAME_REGS = (
    arm.UC_ARM_REG_R0,
    arm.UC_ARM_REG_R1,
    arm.UC_ARM_REG_R2,
    arm.UC_ARM_REG_R3,
    arm.UC_ARM_REG_R12,
    arm.UC_ARM_REG_LR,
    arm.UC_ARM_REG_PC,
    arm.UC_ARM_REG_XPSR,
)
WFI = b"\x30\xbf"
CPSIE_I = b"\x62\xb6"


def unmasking_sites(code: bytes, base: int) -> tuple[list[int], list[int]]:
    """(addresses of ``wfi``, addresses right after ``cpsie i`` or ``msr primask, rN``)
    in Thumb code ``code`` loaded at ``base``. A match inside data only adds a hook at an
    address no instruction starts at, which never fires, or a harmless extra look."""
    wfi, after = [], []
    for offset in range(0, len(code) - 1, 2):
        half = code[offset : offset + 2]
        if half == WFI:
            wfi.append(base + offset)
        elif half == CPSIE_I:
            after.append(base + offset + 2)
        elif (
            offset + 4 <= len(code)
            and half[1] == 0xF3
            and half[0] & 0xF0 == 0x80
            and code[offset + 2] == 0x10  # SYSm 16: PRIMASK
            and code[offset + 3] == 0x88
        ):
            after.append(base + offset + 4)
    return wfi, after


def _native(function: object) -> object:
    """A ctypes function of unicorn's library as a cffi ``void *``."""
    return ffi.cast("void *", ctypes.cast(function, ctypes.c_void_p).value)


class _Batch:
    """Reads or writes a fixed list of registers in one call to unicorn (its Python
    wrappers cost more than the emulation they wrap, at every exception)."""

    def __init__(self, uch: object, regs: tuple[int, ...]) -> None:
        self._uch = uch
        self.n = len(regs)
        self._ids = (ctypes.c_int * self.n)(*regs)
        self.values = (ctypes.c_uint32 * self.n)()
        base = ctypes.addressof(self.values)
        self._ptrs = (ctypes.c_void_p * self.n)(*(base + 4 * i for i in range(self.n)))

    def read(self) -> list[int]:
        uclib.uc_reg_read_batch(self._uch, self._ids, self._ptrs, self.n)
        return self.values[:]

    def read_one(self) -> int:
        """The first register alone (one call, no list)."""
        uclib.uc_reg_read(self._uch, self._ids[0], self._ptrs[0])
        return self.values[0]

    def write(self, values: list[int]) -> None:
        for i, value in enumerate(values):
            self.values[i] = value & 0xFFFF_FFFF
        uclib.uc_reg_write_batch(self._uch, self._ids, self._ptrs, self.n)


class Cpu:
    """The core. ``nvic`` holds the exception state; ``read32(address)`` reads memory
    (for the vector table)."""

    def __init__(self, nvic: Nvic) -> None:
        self.uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        self.nvic = nvic
        self.counter = ffi.new("mcu_counter *")
        self.counter.stop = _native(uclib.uc_emu_stop)
        self.counter.limit = 0
        self.counter.event_count = 2**64 - 1  # nothing timed in C yet (mcu_usart.h)
        self._io_callbacks: list[tuple[object, object]] = []
        self._hook_counter()
        uch = self.uc._uch
        self._uch = uch
        self._uch_c = ffi.cast("void *", uch.value)
        wfi = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_uint64)(self._on_wfi)
        self._io_callbacks.append((wfi, None))
        self.counter.on_wfi = _native(wfi)
        self._sites: list[tuple[int, int]] = []  # (address, MCU_SITE_*) in watch order
        self._site_arrays: tuple[object, object] = (None, None)  # kept alive for the hook
        self._exc = ffi.new("mcu_exceptions *")
        for field, function in (
            ("reg_read_batch", uclib.uc_reg_read_batch),
            ("reg_write_batch", uclib.uc_reg_write_batch),
            ("mem_read", uclib.uc_mem_read),
            ("mem_write", uclib.uc_mem_write),
            ("reg_read", uclib.uc_reg_read),
            ("reg_write", uclib.uc_reg_write),
            ("emu_start", uclib.uc_emu_start),
        ):
            setattr(self._exc, field, _native(function))
        self._exc.frame = list(FRAME_REGS)
        self._exc.sp = arm.UC_ARM_REG_SP
        # the exception state and decisions in C (mcu_nvic.h): the interrupt hook returns
        # from handlers and tail-chains, the counter's hook takes what an unmask lets in
        n = nvic.c
        n.counter = self.counter
        n.x = self._exc
        n.primask_reg = arm.UC_ARM_REG_PRIMASK
        self.counter.nvic = n
        self._native_hook(UC_HOOK_INTR, lib.mcu_nvic_interrupt_hook(), n, 1, 0)
        self._sp = _Batch(uch, (arm.UC_ARM_REG_SP,))
        self._primask = _Batch(uch, (arm.UC_ARM_REG_PRIMASK,))
        self._word = ctypes.create_string_buffer(32)
        self.running = False
        self.sleeping = False
        self._exit_request = False
        self._stopped_by: str | None = None
        self._pc_next = ctypes.c_uint32()
        self.on_sleep: Callable[[], bool] | None = None
        """Called by a ``wfi`` that sleeps, inside the run: True if it let time pass up to
        an exception that wakes the CPU, within the run (the CPU goes on); False to stop
        and sleep as usual."""
        self.lowest_sp = 0xFFFF_FFFF

    @property
    def sleeps(self) -> int:
        """The ``wfi`` instructions that slept (here or in the counter's timed events)."""
        return int(self.counter.sleeps)

    @property
    def lowest_sp(self) -> int:
        """The lowest main stack pointer an exception entry saw."""
        return int(self._exc.lowest_sp)

    @lowest_sp.setter
    def lowest_sp(self, value: int) -> None:
        self._exc.lowest_sp = value

    def _hook_counter(self) -> None:
        self._native_hook(UC_HOOK_CODE, lib.mcu_count_hook(), self.counter, 1, 0)

    def _native_hook(self, kind: int, function: object, data: object, begin: int, end: int) -> None:
        """Hook the C ``function`` (from ``snakebot._core``) as a ``kind`` hook on the
        addresses ``begin``..``end``, with the cffi pointer ``data`` as its data."""
        callback = ctypes.c_void_p(int(ffi.cast("uintptr_t", function)))
        user = ctypes.c_void_p(int(ffi.cast("uintptr_t", data)))
        _add_hook(self.uc._uch, kind, callback, user, begin, end)

    def watch(self, wfi: Iterable[int], after_unmask: Iterable[int]) -> None:
        """Watch the image's ``wfi`` instructions and the instructions after each unmask
        (the counter's hook looks at them: one hook is far cheaper for unicorn than one per
        site, which it would walk on every instruction)."""
        self._sites += [(address, lib.MCU_SITE_WFI) for address in wfi]
        self._sites += [(address, lib.MCU_SITE_AFTER_UNMASK) for address in after_unmask]
        if not self._sites:
            return
        addresses = ffi.new("uint32_t[]", [address for address, _ in self._sites])
        kinds = ffi.new("uint8_t[]", [kind for _, kind in self._sites])
        self._site_arrays = (addresses, kinds)
        c = self.counter
        c.site_address, c.site_kind, c.sites = addresses, kinds, len(self._sites)
        for address, _ in self._sites:
            lib.mcu_watch_site(c, address)

    def map_io(
        self,
        base: int,
        size: int,
        read: Callable[[int, int, int, int], int],
        write: Callable[[int, int, int, int, int], None],
        fast: object = None,
    ) -> None:
        """Send the CPU's accesses to ``base``..``base + size`` to ``read`` and ``write``
        (offset, size[, value]); they call :meth:`fail` with what they raise. ``fast``: an
        ``mcu_fast_io`` whose one register C serves first (``mcu_io_read/write``)."""
        callbacks = (MMIO_READ_CFUNC(read), MMIO_WRITE_CFUNC(write))
        self._io_callbacks.append(callbacks)  # kept alive as long as the CPU
        if fast is None:
            read_fn, write_fn, data = callbacks[0], callbacks[1], None
        else:
            fast.read_fallback = ffi.cast(
                "void *", ctypes.cast(callbacks[0], ctypes.c_void_p).value
            )
            fast.write_fallback = ffi.cast(
                "void *", ctypes.cast(callbacks[1], ctypes.c_void_p).value
            )
            read_fn = ctypes.c_void_p(int(ffi.cast("uintptr_t", lib.mcu_io_read)))
            write_fn = ctypes.c_void_p(int(ffi.cast("uintptr_t", lib.mcu_io_write)))
            data = ctypes.c_void_p(int(ffi.cast("uintptr_t", fast)))
        status = uclib.uc_mmio_map(self._uch, base, size, read_fn, data, write_fn, data)
        if status != 0:
            raise McuFault(f"cannot map I/O at 0x{base:08X} (unicorn error {status})")

    def fail(self, exc: BaseException) -> None:
        """A callback raised ``exc``: stop the CPU; :meth:`run` raises it."""
        if self.uc._hook_exception is None:
            self.uc._hook_exception = exc
        uclib.uc_emu_stop(self._uch)

    # -- time -----------------------------------------------------------------------------

    @property
    def count(self) -> int:
        return int(self.counter.count)

    def stop_soon(self, after: int = 0, until: float = 0.0) -> None:
        """Stop the running CPU within ``after`` more instructions (0: before the next), the
        instructions up to time ``until`` (0: wherever they end; see mcu_count.h's stop_at)."""
        if self.running:
            c = self.counter
            limit = c.count + after
            if limit < c.limit:
                c.limit = limit
            if until < c.stop_at:
                c.stop_at = until

    # -- registers --------------------------------------------------------------------------

    def reg(self, reg: int) -> int:
        return self.uc.reg_read(reg)

    def set_reg(self, reg: int, value: int) -> None:
        self.uc.reg_write(reg, value)

    @property
    def pc(self) -> int:
        return int(lib.mcu_reg(self._uch_c, self._exc, arm.UC_ARM_REG_PC))

    @property
    def primask(self) -> bool:
        return bool(lib.mcu_reg(self._uch_c, self._exc, arm.UC_ARM_REG_PRIMASK) & 1)

    def set_primask(self, masked: bool) -> None:
        self._primask.write([1 if masked else 0])

    def read_memory(self, address: int, size: int) -> bytes:
        buf = self._word if size <= len(self._word) else ctypes.create_string_buffer(size)
        status = uclib.uc_mem_read(self._uch, address, buf, size)
        if status != 0:
            raise McuFault(f"cannot read {size} bytes at 0x{address:08X} (unicorn error {status})")
        return buf.raw[:size]

    def write_memory(self, address: int, data: bytes) -> None:
        status = uclib.uc_mem_write(self._uch, address, data, len(data))
        if status != 0:
            raise McuFault(f"cannot write {len(data)} bytes at 0x{address:08X} (error {status})")

    def read32(self, address: int) -> int:
        return int.from_bytes(self.read_memory(address, 4), "little")

    def boot(self, sp: int, pc: int) -> None:
        """Start at ``pc`` with main stack ``sp``, as from reset: thread mode, privileged,
        interrupts unmasked."""
        uc = self.uc
        for n in range(13):
            uc.reg_write(arm.UC_ARM_REG_R0 + n, 0)
        uc.reg_write(arm.UC_ARM_REG_PRIMASK, 0)
        uc.reg_write(arm.UC_ARM_REG_CONTROL, 0)
        uc.reg_write(arm.UC_ARM_REG_XPSR, 1 << 24)
        uc.reg_write(arm.UC_ARM_REG_SP, sp)
        uc.reg_write(arm.UC_ARM_REG_LR, 0xFFFF_FFFF)
        uc.reg_write(arm.UC_ARM_REG_PC, pc & ~1)
        self.sleeping = False
        self.lowest_sp = sp

    # -- running ----------------------------------------------------------------------------

    def run(self, instructions: int, until: float = 0.0) -> None:
        """Run at most ``instructions`` instructions (fewer if something stops the CPU), the
        instructions up to time ``until`` (0: whatever time they end at; see mcu_count.h's
        stop_at)."""
        if self.sleeping:
            return
        self.counter.stop_at = until
        self._exit_request = False
        self.running = True
        uc = self.uc
        uc._hook_exception = None
        try:
            status = lib.mcu_run(self._uch_c, self._exc, self.counter, instructions)
        finally:
            self.running = False
        if uc._hook_exception is not None:
            exc, uc._hook_exception = uc._hook_exception, None
            raise exc
        n = self.nvic.c
        if n.error:
            self._raise_exception_error()
        if status != 0:
            raise McuFault(
                f"the CPU faulted at 0x{self.pc:08X}: {UcError(status)} "
                f"(after {self.counter.count} instructions)"
            )
        self._stopped_by = None
        if n.fault:
            intno, n.fault = n.fault, 0
            raise McuFault(
                f"the CPU raised exception {intno} at 0x{self.pc:08X} (an undefined "
                "instruction, SVC or breakpoint: none is used by the firmware)"
            )

    def maybe_in_it_block(self) -> bool:
        """Whether the next instruction may sit in an IT block (see mcu_count.h)."""
        return bool(lib.mcu_maybe_in_it_block(self._uch_c, self._exc))

    def _on_wfi(self, address: int) -> int:
        # the hook runs before the instruction: unicorn then halts after it (its WFI ends
        # the run); the CPU sleeps unless an exception is already waiting. 1: it failed
        # (the CPU stops)
        try:
            if self.nvic.takeable(primask=False) is None:
                self.sleeping = True
                self.counter.sleeps += 1
                if self.on_sleep is not None and not self.maybe_in_it_block() and self.on_sleep():
                    self._wake_in_run(address)
            self._stopped_by = "wfi"
        except BaseException as exc:  # stops the CPU; run raises it
            self.fail(exc)
            return 1
        return 0

    def _wake_in_run(self, address: int) -> None:
        """``on_sleep`` woke the CPU within this run: the ``wfi`` at ``address`` is done
        (counted, not executed, so unicorn does not halt) and what may preempt is taken."""
        self.sleeping = False
        self._pc_next.value = (address + 2) | 1
        uclib.uc_reg_write(self._uch, arm.UC_ARM_REG_PC, ctypes.byref(self._pc_next))
        if self.take_exceptions():
            lib.mcu_keep_pc(self._uch_c, self._exc)

    def wake_if_due(self) -> bool:
        """WFI ends when an exception that could preempt (PRIMASK aside) is pending."""
        if self.sleeping and self.nvic.takeable(primask=False) is not None:
            self.sleeping = False
        return not self.sleeping

    # -- exceptions ---------------------------------------------------------------------------

    def take_exceptions(self) -> int:
        """Enter every exception that may preempt now (the last one entered runs first);
        returns how many."""
        taken = lib.mcu_nvic_take(self._uch_c, self.nvic.c)
        if taken < 0:
            self._raise_exception_error()
        if taken:
            self.sleeping = False
        return taken

    def _raise_exception_error(self) -> None:
        """Raise what made an exception entry or return fail (mcu_nvic's error)."""
        n = self.nvic.c
        status, where, exception = n.error, n.error_in, n.error_exception
        n.error = 0
        vtor = self.nvic.vtor
        if where == lib.MCU_NVIC_ENTRY and status == lib.MCU_EXC_NOT_THUMB:
            raise McuFault(
                f"vector {exception} at 0x{vtor + 4 * exception:08X} holds "
                f"0x{self._exc.handler:08X}, not a Thumb address: is VTOR "
                f"(0x{vtor:08X}) pointing at the image's vector table?"
            )
        if where == lib.MCU_NVIC_ENTRY:
            raise McuFault(
                f"exception {exception}: the stack at 0x{self._sp.read_one():08X} "
                "or the vector table is not in memory"
            )
        if status == lib.MCU_EXC_BAD_RETURN:
            raise McuFault(
                f"exception return with EXC_RETURN 0x{self._exc.exc_return | 1:08X} and "
                f"{n.depth} exception(s) active: only returns on the main "
                "stack are modelled"
            )
        raise McuFault(
            f"exception return: the stack at 0x{self._sp.read_one():08X} is not in memory"
        )


def _add_hook(uch: object, kind: int, callback: object, user: object, begin: int, end: int) -> None:
    """unicorn's uc_hook_add of ``callback`` (with ``user`` as its data) on the addresses
    ``begin``..``end`` (1, 0: all of them)."""
    handle = ctypes.c_size_t()
    status = uclib.uc_hook_add(
        uch,
        ctypes.byref(handle),
        kind,
        callback,
        user,
        ctypes.c_uint64(begin),
        ctypes.c_uint64(end),
    )
    if status != 0:
        raise McuFault(f"unicorn refused a hook (error {status})")
