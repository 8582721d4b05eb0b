"""`make firmware` builds both boards with the layout each needs: the CM-530 image at the
ROBOTIS bootloader's application address, the qemu image behind its boot stub, vectors
wired to the right handlers, and the qemu board within its size goal."""

from __future__ import annotations

import re

import pytest
from firmware_support import (
    APP_BASE,
    CM530_DIR,
    QEMU_DIR,
    STUB_BASE,
    build_firmware,
    sections,
    symbols,
)

IRQ_USART1 = 37
IRQ_USART3 = 39
SYSTICK = 15
QEMU_FLASH_GOAL = 32 * 1024
QEMU_RAM = 8 * 1024


@pytest.fixture(scope="module")
def build_output() -> str:
    return build_firmware()


def _word(data: bytes, index: int) -> int:
    return int.from_bytes(data[4 * index : 4 * index + 4], "little")


def _flash_and_ram(elf) -> tuple[int, int]:
    s = sections(elf)
    flash = sum(
        s[name][1]
        for name in (".isr_vector", ".image_info", ".text", ".ARM.exidx", ".data")
        if name in s
    )
    ram = sum(s[name][1] for name in (".data", ".bss", ".stack") if name in s)
    return flash, ram


def parse_ihex(text: str) -> dict[int, int]:
    """Address -> byte from Intel HEX records (types 00, 01, 04, 05), checksums checked."""
    memory: dict[int, int] = {}
    upper = 0
    for line in text.split():
        raw = bytes.fromhex(line[1:])
        assert line[0] == ":" and sum(raw) & 0xFF == 0, f"bad record {line}"
        count, addr, rtype, data = raw[0], int.from_bytes(raw[1:3], "big"), raw[3], raw[4:-1]
        assert len(data) == count
        if rtype == 0:
            for i, b in enumerate(data):
                memory[upper + addr + i] = b
        elif rtype == 4:
            upper = int.from_bytes(data, "big") << 16
        elif rtype == 1:
            break
    return memory


@pytest.mark.parametrize("board", ["cm530", "qemu"])
def test_vector_table_at_application_address(build_output, board):
    d = CM530_DIR if board == "cm530" else QEMU_DIR
    syms = symbols(d / "firmware.elf")
    image = (d / "firmware.bin").read_bytes()
    assert syms["hal_vector_table"] == APP_BASE
    assert sections(d / "firmware.elf")[".isr_vector"][0] == APP_BASE
    ram_top = 0x20010000 if board == "cm530" else 0x20002000
    assert _word(image, 0) == ram_top  # initial stack pointer: the end of RAM
    assert _word(image, 1) == syms["Reset_Handler"] | 1  # Thumb
    assert _word(image, 16 + IRQ_USART1) == syms["USART1_IRQHandler"] | 1
    assert _word(image, 16 + IRQ_USART3) == syms["USART3_IRQHandler"] | 1
    assert _word(image, SYSTICK) == syms["SysTick_Handler"] | 1
    # every other interrupt resets instead of running off into the weeds
    assert _word(image, 16 + 38) == syms["hal_unexpected_irq"] | 1


def test_cm530_image_stays_out_of_the_bootloader_and_the_table_store(build_output):
    s = sections(CM530_DIR / "firmware.elf")
    flash, _ = _flash_and_ram(CM530_DIR / "firmware.elf")
    assert APP_BASE + flash <= 0x0801D000  # BOARD_STORE_BASE (cm530.ld)
    assert all(addr >= APP_BASE for addr, size in s.values() if addr >= 0x08000000 and size)


def test_cm530_hex_holds_the_same_bytes_as_the_bin(build_output):
    image = (CM530_DIR / "firmware.bin").read_bytes()
    memory = parse_ihex((CM530_DIR / "firmware.hex").read_text())
    assert min(memory) == APP_BASE
    assert bytes(memory[APP_BASE + i] for i in range(len(image))) == image


def test_qemu_flash_image_is_stub_then_application(build_output):
    stub = (QEMU_DIR / "stub.bin").read_bytes()
    app = (QEMU_DIR / "firmware.bin").read_bytes()
    flash = (QEMU_DIR / "flash.bin").read_bytes()
    offset = APP_BASE - STUB_BASE
    assert flash[: len(stub)] == stub
    assert set(flash[len(stub) : offset]) == {0xFF}  # erased flash between them
    assert flash[offset:] == app
    assert symbols(QEMU_DIR / "stub.elf")["stub_vectors"] == STUB_BASE
    assert _word(stub, 0) == 0x20002000
    assert len(stub) < offset


def test_qemu_board_meets_its_size_goal(build_output):
    flash, ram = _flash_and_ram(QEMU_DIR / "firmware.elf")
    assert flash < QEMU_FLASH_GOAL
    assert ram <= QEMU_RAM


def test_build_reports_flash_and_ram_for_both_boards(build_output):
    for board in ("cm530", "qemu"):
        flash, ram = _flash_and_ram((CM530_DIR if board == "cm530" else QEMU_DIR) / "firmware.elf")
        m = re.search(rf"^{board}\s+firmware: flash\s+(\d+) B.*RAM\s+(\d+) B", build_output, re.M)
        assert m, build_output
        assert (int(m.group(1)), int(m.group(2))) == (flash, ram)
