"""`snakebot flash` end to end: the emulated bootloader stores the image and, on GO, hands
the line over to QEMU running exactly what it stored (the qemu board's boot stub, then the
image). The flasher then waits for the firmware it sent to answer PING and has the
firmware compute the CRC-32 of its own image in flash: a flash that stored one bit wrong,
although its checksum report matched, is caught there."""

from __future__ import annotations

import json
import zlib

import pytest
from click.testing import CliRunner
from firmware_support import QEMU_DIR, build_firmware

from snakebot.cli import main
from snakebot.sim.bootloader import (
    APP_BASE,
    Bootloader,
    BootloaderFaults,
    BootloaderPty,
    QemuHandover,
)

pytestmark = [pytest.mark.qemu, pytest.mark.serial, pytest.mark.timeout(120)]


@pytest.fixture(autouse=True)
def waits(monkeypatch):
    monkeypatch.setenv("SNAKEBOT_FLASH_QUIET_S", "0.05")
    monkeypatch.setenv("SNAKEBOT_FLASH_GO_TIMEOUT_S", "0.2")
    monkeypatch.setenv("SNAKEBOT_FLASH_BOOT_TIMEOUT_S", "30")  # QEMU on a loaded machine


def flash_into_qemu(faults: BootloaderFaults | None = None):
    build_firmware()
    image = QEMU_DIR / "firmware.bin"
    handover = QemuHandover()
    boot = Bootloader(silence_s=0.3, faults=faults or BootloaderFaults())
    try:
        with BootloaderPty(boot, pace=False, on_go=handover) as server:
            result = CliRunner().invoke(
                main, ["flash", str(image), "--force", "--port", server.device, "--json"]
            )
            with server.lock:
                started = list(boot.started)
    finally:
        handover.close()
    return result, started, image.read_bytes()


def test_the_flashed_firmware_answers_and_verifies_its_own_image():
    result, started, image = flash_into_qemu()
    assert result.exit_code == 0, result.output
    assert started == [APP_BASE]
    report = json.loads(result.stdout)
    assert report["verified"] is True
    assert report["firmware_crc"] == zlib.crc32(image)
    assert "Verified: controller at ID 200" in result.stderr


def test_flash_that_stored_a_bit_wrong_is_caught_by_the_firmware():
    result, started, _ = flash_into_qemu(BootloaderFaults(flash_corrupt=True))
    assert started == [APP_BASE]  # the checksum report matched: GO was sent
    assert result.exit_code == 1, result.output
    assert "FIRMWARE_CRC_MISMATCH" in result.stderr
    assert "press MODE or power-cycle the CM-530" in result.stderr
