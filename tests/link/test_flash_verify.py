"""Verified flashing: after GO the new firmware must answer PING, report the model number
and the image's firmware version, and, asked with Upload Commit FIRMWARE_CHECK, find the
CRC-32 of its own image in flash equal to the CRC-32 of the bytes sent. The controller
side runs on both emulated boards (the real firmware reading its real flash image: the
CM-530's on the emulated STM32F103RE, the qemu board's in QEMU); the host's wait is
bounded when nothing answers."""

from __future__ import annotations

import dataclasses
import os
import pty
import time
import zlib

import pytest
from ctl_support import CTL, Device
from firmware_support import BOARDS, QEMU_DIR, build_firmware, cm530_image
from firmware_support import running as board_running

from snakebot.link.controller import UploadResult
from snakebot.link.controller.client import ControllerClient
from snakebot.link.flash import FlashError, FlashTimeouts
from snakebot.link.flash.image import image_info
from snakebot.link.flash.verify import verify_firmware
from snakebot.sim.bootloader import APP_BASE

TIMEOUTS = FlashTimeouts.resolve(boot=20.0)


@pytest.fixture(scope="module", params=BOARDS)
def running(request, tmp_path_factory):
    """The board's image running (behind the CM-530's bootloader area, or QEMU's boot
    stub), its PC link, and that application's bytes as the flasher would have sent
    them."""
    build_firmware()
    board = request.param
    image = cm530_image() if board == "cm530" else (QEMU_DIR / "firmware.bin").read_bytes()
    with board_running(board, tmp_path_factory.mktemp("bus")) as fw:
        yield fw.pc_link, image


@pytest.mark.qemu
@pytest.mark.serial
def test_the_running_image_is_verified(running):
    port, image = running
    info = image_info(image, APP_BASE)
    done = verify_firmware(port, image, info, TIMEOUTS)
    assert done.crc == zlib.crc32(image)
    assert (done.model_number, done.firmware_version) == (CTL.model_number, info.firmware_version)


@pytest.mark.qemu
@pytest.mark.serial
def test_a_different_image_is_caught_by_the_controller(running):
    port, image = running
    info = image_info(image, APP_BASE)
    changed = bytearray(image)
    changed[-10] ^= 0x40  # same length, same identity block: only the CRC can tell
    with pytest.raises(FlashError, match="FIRMWARE_CRC_MISMATCH.*flash it again"):
        verify_firmware(port, bytes(changed), info, TIMEOUTS)
    with pytest.raises(FlashError, match="FIRMWARE_LENGTH_MISMATCH"):
        verify_firmware(port, image + b"\0", info, TIMEOUTS)
    older = dataclasses.replace(info, firmware_version=info.firmware_version + 1)
    with pytest.raises(FlashError, match="the old firmware is still running"):
        verify_firmware(port, image, older, TIMEOUTS)


@pytest.mark.qemu
@pytest.mark.serial
def test_firmware_check_refuses_a_length_the_flash_cannot_hold(running):
    port, _ = running
    with ControllerClient.open(port) as ctl:
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
