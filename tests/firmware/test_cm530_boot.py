"""The exact CM-530 image (build/cm530/firmware.bin) on the emulated STM32F103RE: from a
cold reset to answering on its PC link, through a real pseudo-terminal, with the host's
own controller client; and what the boot leaves in the chip's registers."""

from __future__ import annotations

import pytest
from firmware_support import cm530_image

from snakebot.facts.boards import APP_BASE, PC_LINK_BAUD, TABLE_CAPACITY
from snakebot.link.controller.client import ControllerClient
from snakebot.sim.mcu.board import Cm530
from snakebot.sim.mcu.runner import McuFirmware

pytest.importorskip("unicorn")


@pytest.fixture(scope="module")
def image() -> bytes:
    return cm530_image()


def test_cold_boot_sets_up_the_chip_as_the_cm530_needs(image: bytes) -> None:
    assert_boots_as_the_cm530_needs(image)


def assert_boots_as_the_cm530_needs(image: bytes) -> None:
    """Boot ``image`` from a cold reset; the chip is set up as the board needs (also run
    on deliberately broken builds by test_cm530_mutants.py, where it must fail)."""
    board = Cm530(image)
    board.run_for(0.02)
    m = board.mcu
    assert m.nvic.vtor == APP_BASE  # the reset handler points VTOR at its own table
    assert m.rcc.clocks().sysclk == 72_000_000 and m.rcc.clocks().pclk1 == 36_000_000
    assert m.flash.acr & 7 == 2
    assert m.afio.usart1_remapped
    assert m.usart1.baud == pytest.approx(1_000_000, rel=0.01)
    assert m.usart3.baud == pytest.approx(PC_LINK_BAUD, rel=0.01)
    port_b = m.gpio["B"]
    assert port_b.output(4) is False and port_b.output(5) is True  # bus idle: receiving
    assert m.iwdg.running and m.systick.fired >= 5  # 1 ms ticks after ~10 ms of start-up
    assert m.resets == []


def test_answers_ping_through_a_pty_with_the_controller_client(image: bytes) -> None:
    with McuFirmware(image) as fw, ControllerClient.open(fw.pc_link) as client:
        info = client.identify()
        regs = client.read("Board", "Table Capacity")
    assert fw.error is None
    assert info["ID"] == client.id
    assert regs["Table Capacity"] == TABLE_CAPACITY["cm530"]
    assert regs["Board"] == 1  # CTL_BOARD_CM530
