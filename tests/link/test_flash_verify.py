"""Verified flashing: after GO the new firmware must answer PING, report the model number
and the image's firmware version, and, asked with Upload Commit FIRMWARE_CHECK, find the
CRC-32 of its own image in flash equal to the CRC-32 of the bytes sent. The controller
side runs in QEMU (the real firmware reading its real flash image); the host's wait is
bounded when nothing answers."""

from __future__ import annotations

import dataclasses
import os
import pty
import time
import zlib

import pytest
from ctl_support import CTL, Device
from firmware_support import QEMU_DIR, build_firmware

from snakebot.link.controller import UploadResult
from snakebot.link.controller.client import ControllerClient
from snakebot.link.flash import FlashError, FlashTimeouts
from snakebot.link.flash.image import image_info
from snakebot.link.flash.verify import verify_firmware
from snakebot.sim.bootloader import APP_BASE
from snakebot.sim.qemu import QemuFirmware

TIMEOUTS = FlashTimeouts.resolve(boot=20.0)


@pytest.fixture(scope="module")
def running():
    """QEMU running the qemu board's image (the boot stub, then the application), and
    that application's bytes as the flasher would have sent them."""
    build_firmware()
    image = (QEMU_DIR / "firmware.bin").read_bytes()
    with QemuFirmware() as fw:
        yield fw, image


@pytest.mark.qemu
@pytest.mark.serial
def test_the_running_image_is_verified(running):
    fw, image = running
    info = image_info(image, APP_BASE)
    done = verify_firmware(fw.ports.pc_link, image, info, TIMEOUTS)
    assert done.crc == zlib.crc32(image)
    assert (done.model_number, done.firmware_version) == (CTL.model_number, info.firmware_version)


@pytest.mark.qemu
@pytest.mark.serial
def test_a_different_image_is_caught_by_the_controller(running):
    fw, image = running
    info = image_info(image, APP_BASE)
    changed = bytearray(image)
    changed[-10] ^= 0x40  # same length, same identity block: only the CRC can tell
    with pytest.raises(FlashError, match="FIRMWARE_CRC_MISMATCH.*flash it again"):
        verify_firmware(fw.ports.pc_link, bytes(changed), info, TIMEOUTS)
    with pytest.raises(FlashError, match="FIRMWARE_LENGTH_MISMATCH"):
        verify_firmware(fw.ports.pc_link, image + b"\0", info, TIMEOUTS)
    older = dataclasses.replace(info, firmware_version=info.firmware_version + 1)
    with pytest.raises(FlashError, match="the old firmware is still running"):
        verify_firmware(fw.ports.pc_link, image, older, TIMEOUTS)


@pytest.mark.qemu
@pytest.mark.serial
def test_firmware_check_refuses_a_length_the_flash_cannot_hold(running):
    fw, _ = running
    with ControllerClient.open(fw.ports.pc_link) as ctl:
        commit = CTL.enums["Upload Commit"]["FIRMWARE_CHECK"]
        for length, code in (
            (0, UploadResult.FIRMWARE_BAD_LENGTH),
            (16, UploadResult.FIRMWARE_LENGTH_MISMATCH),
        ):
            ctl.write({"Upload Length": length, "Upload CRC": 0, "Upload Commit": commit})
            assert ctl.read("Upload Result")["Upload Result"] == code


def test_a_build_without_an_image_says_it_cannot_check():
    """The core as the host builds it (the emulated controller) has no flash image."""
    d = Device()
    assert d.set("Upload Length", 100) == 0
    assert d.set("Upload Commit", CTL.enums["Upload Commit"]["FIRMWARE_CHECK"]) == 0
    assert d.get("Upload Result") == UploadResult.FIRMWARE_UNAVAILABLE


def test_silence_after_go_ends_in_bounded_time_with_the_fix():
    build_firmware()
    image = (QEMU_DIR / "firmware.bin").read_bytes()
    info = image_info(image, APP_BASE)
    master, slave = pty.openpty()
    try:
        waits: list[float] = []
        start = time.monotonic()
        with pytest.raises(FlashError, match="did not answer PING at ID 200 within 1 s of GO"):
            verify_firmware(
                os.ttyname(slave), image, info, FlashTimeouts.resolve(boot=1.0), waits.append
            )
        assert time.monotonic() - start < 5
        assert waits and waits == sorted(waits)  # progress was reported while waiting
    finally:
        os.close(master)
        os.close(slave)
