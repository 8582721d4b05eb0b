"""The emulated STM32F103 as a whole: what the CPU runs after the flash is programmed."""

from __future__ import annotations

from unicorn import arm_const as arm

from snakebot.sim.mcu import flash as fl
from snakebot.sim.mcu.machine import RAM_BASE, Stm32f103

PAGE = 0x0800_0800
MOVS_R0 = 0x2000  # movs r0, #imm8
LOOP = b"\xfe\xe7"  # b .


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
