"""`snakebot flash` end to end against the emulated ROBOTIS bootloader on a real pty."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from flash_support import make_image, serve

from snakebot.cli import main
from snakebot.sim.bootloader import APP_BASE, Bootloader, BootloaderFaults

pytestmark = pytest.mark.timeout(60)  # every wait has a bound: nothing may hang

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(autouse=True)
def quick_waits(monkeypatch):
    # The bootloader's waits stay generous; only the host's idle listening is shortened.
    monkeypatch.setenv("SNAKEBOT_FLASH_QUIET_S", "0.05")
    monkeypatch.setenv("SNAKEBOT_FLASH_GO_TIMEOUT_S", "0.2")


def run(*args: str):
    # The emulated bootloader does not start a controller after GO: nothing to verify.
    return CliRunner().invoke(main, ["flash", "--no-verify", *args])


def sum8(data: bytes) -> int:
    return sum(data) & 0xFF


def test_flash_stores_the_image_byte_for_byte_and_starts_it(tmp_path):
    image = make_image(tmp_path / "fw.bin", 2000)
    boot = Bootloader(silence_s=0.3)
    # The board "runs its application" for 0.3 s, then the user presses MODE; the line
    # is paced at 57600 baud, as on the real link.
    with serve(boot, reset_after_s=0.3, pace=True) as server:
        result = run(str(tmp_path / "fw.bin"), "--port", server.device)
        with server.lock:
            stored, started, commands = boot.image, list(boot.started), list(boot.commands)
        assert server.error is None
    assert result.exit_code == 0, result.output
    trailer = sum8(image)
    assert stored == image + bytes([trailer])
    assert started == [APP_BASE]
    assert commands == ["L", "GO"]
    out = result.stdout
    assert "Press MODE on the CM-530 or power-cycle it now" in out
    assert f"Wrote {len(image) + 1} bytes in " in out and "kbit/s)" in out
    # The emulator sums every byte it received, trailer included.
    assert f"Checksum verified (0x{sum8(image + bytes([trailer])):02X}" in out
    assert "Go 0x08003000" in out


@pytest.mark.slow
@pytest.mark.serial  # paced at line speed with a stall deadline: nothing beside it
def test_an_image_bigger_than_the_pty_buffers_goes_through_at_line_speed(tmp_path):
    """A pty (like a driver) takes ~20 KB at once, then holds the writer until its reader
    has drained nearly all of it: at 57600 baud that is seconds, and must not be taken
    for a stalled link."""
    image = make_image(tmp_path / "fw.bin", 24 * 1024, seed=6)
    boot = Bootloader(silence_s=0.3)
    with serve(boot, pace=True) as server:
        result = run(str(tmp_path / "fw.bin"), "--port", server.device, "--json")
        with server.lock:
            stored = boot.image
    assert result.exit_code == 0, result.output
    assert stored == image + bytes([sum8(image)])
    report = json.loads(result.stdout)
    # Paced at 57600 baud 8N1, the payload cannot beat 46.08 kbit/s.
    assert report["kbit_s"] <= 57600 * 8 / 10 / 1000


def test_no_checksum_byte_no_go_and_json(tmp_path):
    image = make_image(tmp_path / "fw.bin", 1500, seed=2)
    boot = Bootloader(silence_s=0.3)
    with serve(boot) as server:
        result = run(
            str(tmp_path / "fw.bin"),
            "--port",
            server.device,
            "--no-checksum-byte",
            "--no-go",
            "--json",
        )
        with server.lock:
            stored, started, commands = boot.image, list(boot.started), list(boot.commands)
    assert result.exit_code == 0, result.output
    assert stored == image
    assert started == [] and commands == ["L"]
    report = json.loads(result.stdout)
    assert report["image_bytes"] == report["bytes_sent"] == len(image)
    assert report["checksum_byte"] is None
    assert report["checksum"] == sum8(image)
    assert report["started"] is False
    assert "ROBOTIS CM-530 boot loader" in report["banner"]
    assert "Checksum verified" in result.stderr  # human messages stay off stdout


def test_bootloader_that_does_not_count_the_trailer_is_still_verified(tmp_path):
    image = make_image(tmp_path / "fw.bin", 1024, seed=3)
    boot = Bootloader(silence_s=0.3, sum_excludes_last=True)
    with serve(boot) as server:
        result = run(str(tmp_path / "fw.bin"), "--port", server.device, "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["checksum"] == sum8(image)
    assert report["checksum_meaning"] == "the sum of the image without its checksum byte"


def test_corrupted_image_fails_on_the_checksum_and_is_not_started(tmp_path):
    image = make_image(tmp_path / "fw.bin", 1024, seed=4)
    trailer = sum8(image)
    # The flipped bit must not happen to produce the other accepted sum.
    assert (2 * trailer + 1) & 0xFF != trailer and (2 * trailer - 1) & 0xFF != trailer
    boot = Bootloader(silence_s=0.3, faults=BootloaderFaults(corrupt=True))
    with serve(boot) as server:
        result = run(str(tmp_path / "fw.bin"), "--port", server.device)
        with server.lock:
            started = list(boot.started)
    assert result.exit_code == 1
    assert "error[E407]: checksum mismatch" in result.stderr
    assert "NOT started" in result.stderr
    assert started == []


def test_no_answer_to_hash(tmp_path, monkeypatch):
    make_image(tmp_path / "fw.bin", 512)
    with serve(Bootloader(faults=BootloaderFaults(mute=True))) as server:
        result = run(str(tmp_path / "fw.bin"), "--port", server.device, "--reset-timeout", "0.4")
    assert result.exit_code == 1
    assert "error[E401]: no answer from the CM-530 bootloader" in result.stderr
    assert "press MODE or power-cycle the CM-530" in result.stderr


def test_no_ready_after_load(tmp_path, monkeypatch):
    monkeypatch.setenv("SNAKEBOT_FLASH_READY_TIMEOUT_S", "0.4")
    make_image(tmp_path / "fw.bin", 512)
    with serve(Bootloader(faults=BootloaderFaults(no_ready=True))) as server:
        result = run(str(tmp_path / "fw.bin"), "--port", server.device)
    assert result.exit_code == 1
    assert "did not answer the load command" in result.stderr
    assert "'Ready..'" in result.stderr


def test_client_at_the_wrong_baud_is_not_heard():
    """The emulator drops bytes sent at another rate, as a UART would garble them."""
    import serial

    with serve(Bootloader()) as server:
        with serial.Serial(server.device, 115200, timeout=0.3) as port:
            port.write(b"#")
            assert port.read(64) == b""
            port.baudrate = 57600
            port.write(b"#")
            assert b"boot loader" in port.read(400)
        assert server.dropped == 1


def test_missing_port(tmp_path):
    make_image(tmp_path / "fw.bin", 512)
    result = run(str(tmp_path / "fw.bin"), "--port", "/dev/ttySNAKEBOT-missing")
    assert result.exit_code == 2
    assert "/dev/ttySNAKEBOT-missing does not exist" in result.stderr


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("missing.bin", None, "not found: build it with make firmware"),
        ("empty.bin", b"", "is empty"),
        ("fw.hex", b":020000040800F2\n", "holds no bytes to load"),
        ("fw.elf", b"\x7fELF\x01\x01\x01", "not a readable ELF file"),
        ("disguised.bin", b"\x7fELF\x01\x01\x01\x00", "not a readable ELF file"),
        ("hex.bin", b":10000000000001207133000800000000000000004F\n", "not a valid Intel HEX"),
        (
            "low.bin",
            (0x20010000).to_bytes(4, "little") + (0x08000101).to_bytes(4, "little"),
            "linked for another address",
        ),
        (
            "nostack.bin",
            (0x12345678).to_bytes(4, "little") + (0x08003101).to_bytes(4, "little"),
            "outside the CM-530's RAM",
        ),
    ],
)
def test_bad_images_are_refused_before_touching_the_port(tmp_path, name, content, message):
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    # The port does not exist: the image check must come first.
    result = run(str(path), "--port", "/dev/ttySNAKEBOT-missing")
    assert result.exit_code == 2
    assert message in result.stderr
    assert "does not exist" not in result.stderr


def test_oversized_image_is_refused(tmp_path):
    make_image(tmp_path / "big.bin", 500 * 1024 + 1)
    result = run(str(tmp_path / "big.bin"), "--port", "/dev/ttySNAKEBOT-missing")
    assert result.exit_code == 2
    assert "512001 bytes, more than the 512000 bytes (500 KB)" in result.stderr


def test_bad_timeout_setting_is_an_error(tmp_path, monkeypatch):
    make_image(tmp_path / "fw.bin", 512)
    monkeypatch.setenv("SNAKEBOT_FLASH_CHECKSUM_TIMEOUT_S", "soon")
    result = run(str(tmp_path / "fw.bin"), "--port", "/dev/ttySNAKEBOT-missing")
    assert result.exit_code == 2
    assert "SNAKEBOT_FLASH_CHECKSUM_TIMEOUT_S='soon'" in result.stderr


def test_the_built_firmware_goes_through(tmp_path):
    firmware = REPO / "build" / "cm530" / "firmware.bin"
    if not firmware.exists():
        pytest.skip("build/cm530/firmware.bin not built (make firmware)")
    boot = Bootloader(silence_s=0.3)
    with serve(boot) as server:
        result = run(str(firmware), "--port", server.device)
        with server.lock:
            stored = boot.image
    assert result.exit_code == 0, result.output
    data = firmware.read_bytes()
    assert stored == data + bytes([sum8(data)])


def test_sim_bootloader_command_serves_a_flash_from_another_process(tmp_path):
    import signal
    import subprocess
    import sys

    image = make_image(tmp_path / "fw.bin", 700, seed=5)
    link = tmp_path / "ttyCM530"
    server = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "snakebot",
            "sim",
            "bootloader",
            "--link",
            str(link),
            "--json",
            "--silence",
            "0.3",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        hello = json.loads(server.stdout.readline())
        assert hello["link"] == str(link) and hello["baud"] == 57600
        result = run(str(tmp_path / "fw.bin"), "--port", str(link))
        assert result.exit_code == 0, result.output
        server.send_signal(signal.SIGTERM)
        out, err = server.communicate(timeout=20)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    assert server.returncode == 143, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary == {
        "image": 1,
        "bytes": len(image) + 1,
        "checksum": sum8(image + bytes([sum8(image)])),
    }
    assert not link.exists()
