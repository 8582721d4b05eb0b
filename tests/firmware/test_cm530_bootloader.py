"""The flash rehearsal that `snakebot sim bootloader --help` shows, end to end: the
emulated bootloader receives build/cm530/firmware.bin from `snakebot flash`, and after GO
hands its line to that image running on the emulated STM32F103RE, so the flasher's own
verification (PING at the controller's ID, the image's CRC-32 read back) passes. An image
the board cannot start ends the emulated bootloader with one line and exit status 2."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.firmware import image as firmware_image

pytest.importorskip("unicorn")
pytestmark = [pytest.mark.slow, pytest.mark.serial, pytest.mark.timeout(120)]  # real time


def _bootloader(link: Path) -> subprocess.Popen[str]:
    server = subprocess.Popen(
        [sys.executable, "-m", "snakebot", "sim", "bootloader", "--link", str(link), "--json"]
        + ["--no-pace", "--silence", "0.3"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert server.stdout is not None
    hello = json.loads(server.stdout.readline())
    assert hello["link"] == str(link)
    return server


def _image(board: str) -> Path:
    path = firmware_image(board, "firmware.bin")
    if not path.is_file():
        pytest.skip(f"build/{board}/firmware.bin is not built: make firmware")
    return path


def test_flash_to_the_emulated_bootloader_ends_verified(tmp_path):
    image = _image("cm530")
    link = tmp_path / "ttyCM530"
    server = _bootloader(link)
    try:
        result = CliRunner().invoke(
            main, ["flash", str(image), "--port", str(link)], env={"SNAKEBOT_MARGIN_MS": "3000"}
        )
        assert result.exit_code == 0, result.output
        assert "Verified: controller at ID 200" in result.output
        server.terminate()
        _, err = server.communicate(timeout=20)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    assert server.returncode == 143, err
    assert "Traceback" not in err


def test_another_boards_image_stops_the_bootloader_with_one_line_and_status_2(tmp_path):
    image = _image("qemu")
    link = tmp_path / "ttyCM530"
    server = _bootloader(link)
    try:
        result = CliRunner().invoke(
            main,
            ["flash", str(image), "--port", str(link), "--force", "--no-verify"],
        )
        # sent, checked and started: the emulated board refuses to run it and its line goes
        # away, which the flasher reports as a runtime failure
        assert result.exit_code == 1, result.output
        assert "internal error" not in result.output
        _, err = server.communicate(timeout=20)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    assert server.returncode == 2
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "built for the qemu board, not the CM-530" in lines[0], err
    assert not link.exists()
