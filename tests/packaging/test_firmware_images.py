"""Which firmware image the commands use: the one built in this checkout, else the one
shipped in the package; and `snakebot flash` without an image flashes that one."""

from __future__ import annotations

import pytest
from click.testing import CliRunner
from firmware_support import build_firmware

import snakebot.firmware as fw
from snakebot.cli import main
from snakebot.sim.bootloader import Bootloader, BootloaderPty


@pytest.fixture
def no_build(tmp_path, monkeypatch):
    """A checkout whose build/ is empty."""
    monkeypatch.setattr(fw, "BUILD_DIR", tmp_path / "build")


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """An installed package: no checkout around it, its images under ``tmp_path``."""
    monkeypatch.setattr(fw, "in_checkout", lambda: False)
    monkeypatch.setattr(fw, "shipped_image", lambda b, n: tmp_path / "images" / b / n)


def test_the_checkouts_build_is_used_when_it_exists():
    build_firmware()
    assert fw.image("qemu", "firmware.elf") == fw.BUILD_DIR / "qemu" / "firmware.elf"


def test_a_checkout_without_a_build_points_at_where_make_firmware_puts_it(no_build):
    assert fw.image("cm530", "firmware.bin") == fw.BUILD_DIR / "cm530" / "firmware.bin"


def test_an_installed_package_uses_its_shipped_images(installed, tmp_path):
    assert fw.image("qemu", "flash.bin") == tmp_path / "images" / "qemu" / "flash.bin"


def test_shipped_images_live_in_the_package():
    path = fw.shipped_image("qemu", "stub.elf")
    assert path.parts[-5:] == ("snakebot", "firmware", "images", "qemu", "stub.elf")


def test_flash_without_an_image_flashes_the_default_one(monkeypatch):
    build_firmware()
    monkeypatch.setenv("SNAKEBOT_FLASH_QUIET_S", "0.05")
    monkeypatch.setenv("SNAKEBOT_FLASH_GO_TIMEOUT_S", "0.2")
    default = fw.image("cm530", "firmware.bin")
    boot = Bootloader(silence_s=0.3)
    with BootloaderPty(boot, reset_after_s=0.1, pace=False) as server:
        result = CliRunner().invoke(main, ["flash", "--no-verify", "--port", server.device])
        with server.lock:
            stored = boot.image
    assert result.exit_code == 0, result.output
    assert f"Flashing {default} " in result.stdout
    assert stored[:-1] == default.read_bytes()  # the image, then its checksum byte
