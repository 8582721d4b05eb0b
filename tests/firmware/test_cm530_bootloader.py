"""The flash rehearsal that `snakebot sim bootloader --help` shows, end to end: the
emulated bootloader receives build/cm530/firmware.bin from `snakebot flash`, and after GO
hands its line to that image running on the emulated STM32F103RE, so the flasher's own
verification (PING at the controller's ID, the image's CRC-32 read back) passes. An image
the board cannot start leaves the line open and silent, as on a board: the flasher's PING
after GO fails, and the emulated bootloader, having said why in one line, ends with exit
status 2 once the flasher has let go of the line."""

from __future__ import annotations

import json
import select
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.firmware import image as firmware_image
from snakebot.sim.bootloader import HANGUP_S

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


def _flash_unstartable(image: Path, tmp_path: Path) -> str:
    """Flash ``image`` (--force: past the flasher's own checks) to an emulated bootloader,
    verifying with a short wait for PING, check that both sides fail as with a board, and
    return the one stderr line the bootloader printed."""
    link = tmp_path / "ttyCM530"
    server = _bootloader(link)
    assert server.stderr is not None
    try:
        result = CliRunner().invoke(
            main,
            ["flash", str(image), "--port", str(link), "--force", "--no-library-backup"],
            env={"SNAKEBOT_FLASH_BOOT_TIMEOUT_S": "2"},
        )
        # sent, checked by the bootloader and started: nothing answers after GO, as on a board
        assert result.exit_code == 1, result.output
        assert "did not answer PING at ID 200 within 2 s of GO" in result.output
        assert "another board" in result.output and "build/cm530/firmware.bin" in result.output
        assert "internal error" not in result.output and "Traceback" not in result.output
        # the line stayed all along, and the bootloader said what is wrong when it happened
        assert link.exists() and server.poll() is None, "the bootloader ended too early"
        assert select.select([server.stderr], [], [], 1.0)[0], "nothing said at GO"
        line = server.stderr.readline()
        server.wait(timeout=HANGUP_S + 5)  # the flasher let go of the line: it ends by itself
        rest = server.stderr.read()
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    assert server.returncode == 2, line + rest
    assert not rest.strip(), rest  # one line in all
    assert not link.exists()
    return line.strip()


def test_another_boards_image_does_not_answer_and_the_flasher_says_so(tmp_path):
    line = _flash_unstartable(_image("qemu"), tmp_path)
    assert line.startswith("error: ") and "built for the qemu board, not the CM-530" in line
    assert "build/cm530/firmware.bin" in line


def test_a_truncated_image_does_not_answer_and_the_flasher_says_so(tmp_path):
    # without --force the flasher refuses it itself (tests/link/test_flash_image.py)
    cut = tmp_path / "cut.bin"
    cut.write_bytes(_image("cm530").read_bytes()[:4096])
    line = _flash_unstartable(cut, tmp_path)
    assert line.startswith("error: ") and "is truncated" in line, line
