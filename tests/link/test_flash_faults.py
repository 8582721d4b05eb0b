"""Faults during a flash, against the emulated bootloader on a real pty: lost bytes, a
wrong checksum, no "Ready", a reset in the middle of the transfer. Each ends in bounded
time with one clear message (exit 1), the new firmware not started, and the board still
recoverable: flashing again, after the user resets it, stores the image byte for byte."""

from __future__ import annotations

import pytest
from click.testing import CliRunner
from flash_support import make_image, serve

from snakebot.cli import main
from snakebot.cli.troubleshooting import ERROR_LINE
from snakebot.sim.bootloader import APP_BASE, Bootloader, BootloaderFaults

pytestmark = pytest.mark.timeout(90)


#: Short waits, so that a fault ends the flash soon. The flash after it, which must
#: succeed, waits as long as a user's would: beside busy processes the emulated
#: bootloader's answers once came later than these.
QUICK_WAITS = {
    "SNAKEBOT_FLASH_QUIET_S": "0.05",
    "SNAKEBOT_FLASH_GO_TIMEOUT_S": "0.2",
    "SNAKEBOT_FLASH_READY_TIMEOUT_S": "0.5",
    "SNAKEBOT_FLASH_CHECKSUM_TIMEOUT_S": "1",
}


@pytest.fixture(autouse=True)
def quick_waits(monkeypatch):
    for name, value in QUICK_WAITS.items():
        monkeypatch.setenv(name, value)
    monkeypatch.setenv("SNAKEBOT_FLASH_RESET_TIMEOUT_S", "5")


def flash(path, device):
    return CliRunner().invoke(
        main, ["flash", "--no-verify", "--no-library-backup", str(path), "--port", device]
    )


@pytest.mark.parametrize(
    ("faults", "message"),
    [
        (BootloaderFaults(drop_every=700), "checksum mismatch"),
        (BootloaderFaults(corrupt=True), "checksum mismatch"),
        (BootloaderFaults(no_ready=True), "did not answer the load command"),
        (BootloaderFaults(reset_after=1500), "sent no 'Checksum:' report"),
    ],
    ids=["lost-bytes", "wrong-checksum", "no-ready", "reset-during-transfer"],
)
def test_a_fault_fails_clearly_and_the_board_recovers(tmp_path, monkeypatch, faults, message):
    image = make_image(tmp_path / "fw.bin", 4000, seed=11)
    boot = Bootloader(silence_s=0.3, faults=faults)
    with serve(boot) as server:
        failed = flash(tmp_path / "fw.bin", server.device)
        with server.lock:
            started = list(boot.started)
            boot.faults = BootloaderFaults()  # the line is good again
        assert failed.exit_code == 1, failed.output
        [line] = failed.stderr.strip().splitlines()
        assert ERROR_LINE.match(line) and message in line
        assert "press MODE or power-cycle the CM-530" in line or "NOT started" in line
        assert "Traceback" not in failed.output
        assert started == []  # nothing half-written was started
        # The user resets the board, then flashes again. (A reset pressed at a fixed
        # time into the second flash came, beside busy processes, in the middle of its
        # transfer: the bootloader read the rest of the image as commands.)
        server.press_reset()
        for name in QUICK_WAITS:
            monkeypatch.delenv(name)
        again = flash(tmp_path / "fw.bin", server.device)
        with server.lock:
            stored, started = boot.image, list(boot.started)
    assert again.exit_code == 0, again.output
    assert stored == image + bytes([sum(image) & 0xFF])
    assert started == [APP_BASE]


def test_lost_bytes_are_lost_in_the_emulator():
    boot = Bootloader(faults=BootloaderFaults(drop_every=3))
    boot.reset(0.0)
    boot.feed(b"#", 0.0)
    boot.feed(b"L\n", 0.0)
    boot.feed(bytes(range(1, 10)), 0.01)
    boot.feed(bytes(range(10, 13)), 0.02)
    boot.poll(1.0)
    assert boot.image == bytes([1, 2, 4, 5, 7, 8, 10, 11])


def test_a_reset_during_the_transfer_leaves_the_board_waiting_for_hash():
    boot = Bootloader(faults=BootloaderFaults(reset_after=5))
    boot.reset(0.0)
    boot.feed(b"#", 0.0)
    boot.feed(b"L\n", 0.0)
    assert boot.feed(b"\x00" * 4, 0.01) == b""
    assert boot.feed(b"\x00" * 4, 0.02) == b""
    assert boot.state == "wait_hash" and boot.images == []
    assert b"boot loader" in boot.feed(b"#", 0.03)
