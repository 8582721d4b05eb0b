"""`snakebot sim serve --board qemu`: the real firmware under QEMU on the emulated bus,
started as a user would (a subprocess), reached through the pseudo-terminal it prints, and
stopped with SIGTERM without leaving QEMU behind (the default board's, the emulated
CM-530's, is tests/firmware/test_cm530_cli.py). Also: the flash image it builds from the
application ELF is the one `make firmware` lays out, and a missing image, one that is no
firmware and one built for the other board are clear errors (exit 2) on either board."""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import subprocess
import sys
import time

import pytest
from click.testing import CliRunner
from firmware_support import BUILD, CONTROLLER_ID, QEMU_DIR, build_firmware, client

from snakebot.cli import main
from snakebot.formats.protocol import Packet
from snakebot.sim.serve import flash_image

START_TIMEOUT_S = 60.0  # QEMU start + boot on a loaded machine
STOP_TIMEOUT_S = 20.0


def _read_line(proc: subprocess.Popen[str], timeout: float) -> str:
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], timeout)
    if not ready:
        raise AssertionError(f"no output from `snakebot sim serve` within {timeout} s")
    return proc.stdout.readline()


def _gone(pid: int, timeout: float) -> bool:
    """True once no process has ``pid`` (QEMU is reaped by the serve process)."""
    end = time.monotonic() + timeout
    while True:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        if time.monotonic() > end:
            return False
        time.sleep(0.05)


@pytest.mark.qemu
def test_serve_answers_on_its_pty_and_sigterm_leaves_no_qemu():
    build_firmware()
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "snakebot",
            "sim",
            "serve",
            "--board",
            "qemu",
            "--robot",
            "snake5",
            "--json",
            "--report",
            "0",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    qemu_pid = None
    try:
        first = json.loads(_read_line(proc, START_TIMEOUT_S))
        assert first["event"] == "serving"
        assert first["servo_ids"] == [10, 11, 15, 16]
        qemu_pid = first["qemu_pid"]
        os.kill(qemu_pid, 0)  # QEMU runs
        with client(first["pc_link"]) as c:
            assert c.ping(CONTROLLER_ID) == Packet(CONTROLLER_ID, 0, b"")
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=STOP_TIMEOUT_S)
        assert proc.returncode == 143, err
        last = json.loads(out.strip().splitlines()[-1])
        assert last["event"] == "stopped"
        assert _gone(qemu_pid, 5.0), f"QEMU (pid {qemu_pid}) is still running"
        assert not os.path.exists(first["bus_socket"])  # the work directory is removed
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        if qemu_pid is not None and not _gone(qemu_pid, 0.0):
            with contextlib.suppress(ProcessLookupError):
                os.kill(qemu_pid, signal.SIGKILL)


BOARD_CHOICE = [[], ["--board", "qemu"]]  # the default board, the CM-530, and QEMU's


@pytest.mark.parametrize("board", BOARD_CHOICE, ids=["default", "qemu"])
def test_a_missing_firmware_image_says_to_build_it(tmp_path, board):
    missing = tmp_path / "firmware.elf"
    result = CliRunner().invoke(main, ["sim", "serve", *board, "--firmware", str(missing)])
    assert result.exit_code == 2
    assert f"firmware image {missing} not found" in result.output
    built = "build/qemu/firmware.elf" if board else "build/cm530/firmware.bin"
    assert f"`make firmware` builds {built}" in result.output


@pytest.mark.parametrize(
    ("board", "says"),
    [([], "not a readable ELF"), (["--board", "qemu"], "32-bit little-endian")],
    ids=["default", "qemu"],
)
def test_a_file_that_is_not_firmware_is_refused(tmp_path, board, says):
    bogus = tmp_path / "firmware.elf"
    bogus.write_bytes(b"\x7fELF" + bytes(60))
    result = CliRunner().invoke(main, ["sim", "serve", *board, "--firmware", str(bogus)])
    assert result.exit_code == 2
    assert says in result.output


@pytest.mark.parametrize(
    ("board", "image", "built_for"),
    [
        ("cm530", "qemu/firmware.elf", "qemu"),
        ("qemu", "cm530/firmware.elf", "cm530"),
        ("qemu", "cm530/firmware.bin", "cm530"),
    ],
)
def test_the_other_boards_build_is_refused_at_once(board, image, built_for):
    """What `make firmware` builds for one board, given to the other: exit 2 in one line
    naming the board it was built for, before anything runs (not a boot that times out)."""
    build_firmware()
    path = BUILD / image
    result = CliRunner().invoke(main, ["sim", "serve", "--board", board, "--firmware", str(path)])
    assert result.exit_code == 2, result.output
    assert result.stdout == "" and result.stderr.count("\n") == 1
    assert f"{path} was built for the {built_for} board" in result.stderr


def test_flash_image_from_the_elf_is_the_one_make_lays_out(tmp_path):
    """The boot stub at 0x08000000, erased flash up to 0x08003000, then the application:
    byte for byte what `make firmware` writes to build/qemu/flash.bin."""
    build_firmware()
    built = flash_image(QEMU_DIR / "firmware.elf", tmp_path / "flash.bin").read_bytes()
    assert built == (QEMU_DIR / "flash.bin").read_bytes()
    raw = flash_image(QEMU_DIR / "flash.bin", tmp_path / "copy.bin").read_bytes()
    assert raw == built
