"""An emulated CM-530 started anywhere in the test suite (in process, or by a command a
test runs) stops at the first access to a register no model knows: tests/conftest.py sets
``SNAKEBOT_MCU_STRICT``, which `McuFirmware` follows unless told otherwise. Without it (as
`sim serve` runs for a user) such a read gives zero and is counted."""

from __future__ import annotations

import os
import time

import pytest

from snakebot.facts.boards import APP_BASE
from snakebot.sim.mcu.errors import UnmodelledAccess
from snakebot.sim.mcu.runner import STRICT_ENV, McuFirmware

pytest.importorskip("unicorn")

# the vector table (stack pointer, reset handler), then: movw r1, #0x1030;
# movt r1, #0x4002; ldr r0, [r1] (RCC's offset 0x30, no register on this chip); b .
READS_UNKNOWN = (
    (0x2000_1000).to_bytes(4, "little")
    + (APP_BASE + 8 | 1).to_bytes(4, "little")
    + bytes.fromhex("41f23001c4f202010868fee7")
)


def ran(fw: McuFirmware, seconds: float = 0.2) -> McuFirmware:
    """``fw`` started, run until it stops with an error or for ``seconds``, stopped."""
    with fw:
        end = time.monotonic() + seconds
        while fw.error is None and time.monotonic() < end:
            time.sleep(0.01)
    return fw


def test_the_suite_runs_every_emulated_board_strict() -> None:
    assert os.environ.get(STRICT_ENV)
    fw = ran(McuFirmware(READS_UNKNOWN))
    assert isinstance(fw.error, UnmodelledAccess), fw.error
    assert "0x40021030" in str(fw.error)


def test_without_the_setting_the_read_gives_zero_and_is_counted(monkeypatch) -> None:
    monkeypatch.delenv(STRICT_ENV)
    fw = ran(McuFirmware(READS_UNKNOWN))
    assert fw.error is None
    assert any("0x40021030" in m for m in fw.board.mcu.rcc.unmodelled)
    assert ran(McuFirmware(READS_UNKNOWN, strict=True)).error is not None  # the keyword wins
