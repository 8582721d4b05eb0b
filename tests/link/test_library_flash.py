"""`snakebot flash` backs the gait library up through the running controller first: against
the emulated ROBOTIS bootloader, whose "application" never answers, it warns and flashes
anyway (the QEMU firmware tests back a real library up and restore it)."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.firmware import image as firmware_image
from snakebot.sim.bootloader import Bootloader, BootloaderPty

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(autouse=True)
def quick_waits(monkeypatch, tmp_path):
    monkeypatch.setenv("SNAKEBOT_FLASH_QUIET_S", "0.05")
    monkeypatch.setenv("SNAKEBOT_FLASH_GO_TIMEOUT_S", "0.2")
    monkeypatch.setenv("SNAKEBOT_LIBRARY_BACKUP_DIR", str(tmp_path / "backups"))


@pytest.mark.parametrize("backup", [True, False], ids=["backup", "no-backup"])
def test_flash_warns_when_no_controller_answers_and_flashes_anyway(tmp_path, backup):
    data = firmware_image("cm530", "firmware.bin").read_bytes()  # what flash sends by default
    boot = Bootloader(silence_s=0.3)
    with BootloaderPty(boot, reset_after_s=0.3, pace=False) as server:
        extra = [] if backup else ["--no-library-backup"]
        result = CliRunner().invoke(main, ["flash", "--no-verify", "--port", server.device, *extra])
        with server.lock:
            stored = boot.image
    assert result.exit_code == 0, result.output
    assert stored is not None and stored[: len(data)] == data
    warned = "no snakebot controller answered" in result.stderr
    assert warned == backup
    assert "not backed up" in result.stderr if backup else result.stderr == ""
    assert not (tmp_path / "backups").exists()


def test_restore_refuses_a_file_that_is_not_a_backup(tmp_path):
    bad = tmp_path / "nope.json"
    bad.write_text("[1, 2]")
    result = CliRunner().invoke(main, ["library", "restore", str(bad), "--port", "/dev/null"])
    assert result.exit_code == 2
    assert result.stderr.startswith("error: ") and "not a snakebot library backup" in result.stderr
    assert result.stderr.count("\n") == 1
