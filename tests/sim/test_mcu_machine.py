"""The emulated STM32F103 as a whole: what the CPU runs after the flash is programmed."""

from __future__ import annotations

import random

import pytest
from unicorn import arm_const as arm

from snakebot.core import ffi, lib
from snakebot.sim.mcu import flash as fl
from snakebot.sim.mcu import nvic, rcc, usart
from snakebot.sim.mcu.errors import McuFault
from snakebot.sim.mcu.machine import RAM_BASE, Stm32f103

PAGE = 0x0800_0800
MOVS_R0 = 0x2000  # movs r0, #imm8
LOOP = b"\xfe\xe7"  # b .
BX_LR = b"\x70\x47"


def test_code_programmed_into_the_flash_runs_instead_of_what_was_there() -> None:
    m = Stm32f103(hse_hz=8_000_000)
    m.load(PAGE, (MOVS_R0 | 1).to_bytes(2, "little") + LOOP)
    m.cpu.boot(RAM_BASE + 0x1000, PAGE | 1)
    m.run_until(1e-5)
    assert m.cpu.reg(arm.UC_ARM_REG_R0) == 1
    f = m.flash
    for value in (fl.KEY1, fl.KEY2):
        f.write(fl.KEYR, 4, value)
    f.write(fl.CR, 4, fl.CR_PER)
    f.write(fl.AR, 4, PAGE)
    f.write(fl.CR, 4, fl.CR_PER | fl.CR_STRT)
    f.write(fl.CR, 4, fl.CR_PG)
    f.program(PAGE, 2, MOVS_R0 | 2)
    f.program(PAGE + 2, 2, int.from_bytes(LOOP, "little"))
    assert m.read(PAGE, 4) == (MOVS_R0 | 2).to_bytes(2, "little") + LOOP
    m.cpu.boot(RAM_BASE + 0x1000, PAGE | 1)
    m.run_until(m.now() + 1e-5)
    assert m.cpu.reg(arm.UC_ARM_REG_R0) == 2  # not the code translated before


def test_code_in_ram_runs_and_code_stored_over_it_runs_next() -> None:
    # RAM is mapped without execute permission until the CPU first fetches from it; then
    # the CPU's stores over code it ran drop that code's translation, as before
    m = Stm32f103(hse_hz=8_000_000)
    m.load(RAM_BASE + 0x100, (MOVS_R0 | 3).to_bytes(2, "little") + BX_LR)
    calls_twice = bytes.fromhex(
        "40f20011"  # movw r1, #0x0100
        "c2f20001"  # movt r1, #0x2000
        "4b1c"  # adds r3, r1, #1
        "9847"  # blx r3: movs r0, #3 in RAM
        "42f20402"  # movw r2, #0x2004 (movs r0, #4)
        "0a80"  # strh r2, [r1]: over the movs r0, #3 just run
        "9847"  # blx r3
    )
    m.load(PAGE, calls_twice + LOOP)
    m.cpu.boot(RAM_BASE + 0x1000, PAGE | 1)
    m.run_until(1e-5)
    assert m.cpu.reg(arm.UC_ARM_REG_R0) == 4
    assert m.cpu.pc == PAGE + len(calls_twice)


def test_code_loaded_into_ram_over_code_already_run_runs_next() -> None:
    m = Stm32f103(hse_hz=8_000_000)
    code = RAM_BASE + 0x100
    m.load(code, (MOVS_R0 | 3).to_bytes(2, "little") + LOOP)
    m.cpu.boot(RAM_BASE + 0x1000, code | 1)
    m.run_until(1e-5)
    assert m.cpu.reg(arm.UC_ARM_REG_R0) == 3
    m.load(code, (MOVS_R0 | 4).to_bytes(2, "little"))
    m.cpu.boot(RAM_BASE + 0x1000, code | 1)
    m.run_until(m.now() + 1e-5)
    assert m.cpu.reg(arm.UC_ARM_REG_R0) == 4  # not the code translated before


def _exception_machine(handler_b: bytes = b"") -> Stm32f103:
    """PendSV's handler shifts r5 left by 4 and adds 1, SysTick's adds 2 (or runs
    ``handler_b``); the thread clears r5 and loops."""
    m = Stm32f103(hse_hz=8_000_000)
    code = PAGE + 0x100
    handler_a = bytes.fromhex("2d010135") + BX_LR  # lsls r5, r5, #4; adds r5, #1; bx lr
    handler_b = handler_b or bytes.fromhex("2d010235") + BX_LR
    thread = bytes.fromhex("0025") + LOOP  # movs r5, #0; b .
    vectors = [0] * 16
    vectors[14], vectors[15] = (code | 1), (code + 8) | 1
    table = b"".join(v.to_bytes(4, "little") for v in vectors)
    m.load(PAGE, table.ljust(0x100, b"\0") + handler_a.ljust(8, b"\0") + handler_b + thread)
    m.nvic.vtor = PAGE
    m.cpu.boot(RAM_BASE + 0x1000, (code + 8 + len(handler_b)) | 1)
    m.run_until(1e-6)
    return m


def test_pending_exceptions_are_taken_by_priority_and_tail_chained() -> None:
    m = _exception_machine()
    m.nvic.pend(nvic.PENDSV)
    m.nvic.pend(nvic.SYSTICK)  # the same priority: the lower number first, then the other
    m.run_until(m.now() + 1e-5)
    assert m.cpu.reg(arm.UC_ARM_REG_R5) == 0x12
    assert (m.nvic.active, m.nvic.pending, m.nvic.entries) == ([], 0, 2)
    m.nvic.write(nvic.SHPR1 + nvic.PENDSV - 4, 1, 0x40)  # PendSV below SysTick now
    m.cpu.set_reg(arm.UC_ARM_REG_R5, 0)
    m.nvic.pend(nvic.PENDSV)
    m.nvic.pend(nvic.SYSTICK)
    m.run_until(m.now() + 1e-5)
    assert m.cpu.reg(arm.UC_ARM_REG_R5) == 0x21
    assert m.nvic.entries == 4 and m.cpu.lowest_sp == RAM_BASE + 0x1000 - 32


def test_a_vector_without_the_thumb_bit_and_a_return_to_the_process_stack_are_faults() -> None:
    m = _exception_machine()
    m.nvic.vtor = PAGE + 0x80  # a table of zeros
    m.nvic.pend(nvic.SYSTICK)
    with pytest.raises(McuFault, match="vector 15 at 0x080008BC holds 0x00000000, not a Thumb"):
        m.run_until(m.now() + 1e-5)
    m = _exception_machine(bytes.fromhex("0220c0430047"))  # r0 = ~2: bx 0xFFFFFFFD
    m.nvic.pend(nvic.SYSTICK)
    with pytest.raises(McuFault, match="EXC_RETURN 0xFFFFFFFD and 1 exception.s. active"):
        m.run_until(m.now() + 1e-5)


def _usart_chip(c_side: bool) -> tuple[Stm32f103, list[tuple[int, float]]]:
    m = Stm32f103(hse_hz=8_000_000)
    m.rcc.write(rcc.APB2ENR, 4, 1 << 14)  # USART1's clock
    if not c_side:
        m.usart1.fast.nvic = ffi.NULL  # the Python model serves every access but SR/CR1 reads
    sent: list[tuple[int, float]] = []
    m.usart1.on_tx = lambda byte, start, end, baud: sent.append((byte, start))
    m.usart1.write(usart.BRR, 4, 16)  # 500 kbps at 8 MHz: 20 us a frame
    return m, sent


def test_usart_registers_served_in_c_behave_as_the_model() -> None:
    # the accesses go in where unicorn sends the CPU's (mcu_io_read/write): on one chip C
    # serves DR and CR1 where it can, on the other the Python model serves them all
    rng = random.Random(30)
    chips = [_usart_chip(True), _usart_chip(False)]
    cr1_bits = [usart.CR1_UE, usart.CR1_TE, usart.CR1_RE, usart.CR1_RXNEIE, usart.CR1_TCIE]
    cr1_bits.append(usart.CR1_TXEIE)
    for _ in range(3000):
        op = rng.randrange(6)
        value = rng.randrange(256)
        cr1 = sum(bit for bit in cr1_bits if rng.random() < 0.8)
        dt = rng.choice((0.0, 3e-6, 20e-6, 45e-6))
        seen = []
        for m, sent in chips:
            fast = m.usart1.fast
            if op == 0:
                seen.append(lib.mcu_io_read(ffi.NULL, usart.SR, 4, fast))
            elif op == 1:
                seen.append(lib.mcu_io_read(ffi.NULL, usart.DR, 4, fast))
            elif op == 2:
                lib.mcu_io_write(ffi.NULL, usart.DR, 4, value, fast)
            elif op == 3:
                lib.mcu_io_write(ffi.NULL, usart.CR1, 4, cr1, fast)
            elif op == 4:
                m.usart1.receive(value)
            m.stall(dt)
            m.run_events(m.now())
            u = m.usart1
            seen.append((u.sr, u.cr1, u.tdr, u.rdr, m.nvic.lines, m.nvic.pending, sent[-3:]))
        assert seen[: len(seen) // 2] == seen[len(seen) // 2 :]
    assert len(chips[0][1]) > 200 and chips[0][0].nvic.pending  # bytes sent, lines raised
