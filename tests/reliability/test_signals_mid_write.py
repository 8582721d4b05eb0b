"""SIGTERM and SIGKILL in the middle of the commands that change something (issue #28):
`upload`, `library store`, `flash` and `robot calibrate`, each a real snakebot process
stopped while it is at work. Afterwards nothing is half-written: the controller keeps
its previous table (or the whole new one), a library slot is as it was or as stored,
the robot file is byte for byte the old one with its mode; SIGTERM exits 143 with one
line, SIGKILL leaves no more than SIGTERM does."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import threading
import time
import tty
import zlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest
from controller_cli_support import constant_table, save, wave_table
from flash_support import make_image, serve

from snakebot.link.transport.portlock import PortLock
from snakebot.sim.bootloader import Bootloader
from snakebot.sim.controller_pty import ControllerPty, is_upload_chunk

pytestmark = pytest.mark.timeout(120)

SIGNALS = [signal.SIGTERM, signal.SIGKILL]
IDS = ["SIGTERM", "SIGKILL"]


def _snakebot(*args: str, env: dict[str, str] | None = None) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "snakebot", *map(str, args)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, **(env or {})},
    )


def _wait_for(condition: Callable[[], bool], proc: subprocess.Popen[bytes], what: str) -> None:
    deadline = time.monotonic() + 60
    while not condition():
        assert proc.poll() is None, (what, proc.communicate()[1].decode())
        assert time.monotonic() < deadline, f"never saw {what}"
        time.sleep(0.01)


def _stop(proc: subprocess.Popen[bytes], signum: int) -> str:
    """Send ``signum`` and wait; what it said on stderr. SIGTERM: exit 143, one line."""
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    text = err.decode(errors="replace")
    assert "Traceback" not in text and "internal error" not in text, text
    if signum == signal.SIGTERM:
        assert proc.returncode == 143, text
        assert text.strip().splitlines()[-1] == "interrupted", text
    else:
        assert proc.returncode == -signal.SIGKILL
    return text


def _port_is_free(device: str) -> bool:
    PortLock(device).release()  # raises if someone still holds it
    return True


# -- upload ----------------------------------------------------------------------------------


class HoldAfterFirstChunk:
    """The line goes quiet after the first upload chunk: the upload is then surely under
    way (retrying), neither before it nor committed."""

    def __init__(self) -> None:
        self.seen = threading.Event()

    def __call__(self, index: int, packet: bytes) -> bytes | None:
        if self.seen.is_set():
            return None
        if is_upload_chunk(packet):
            self.seen.set()
        return packet


@pytest.mark.parametrize("signum", SIGNALS, ids=IDS)
def test_upload_stopped_mid_table_leaves_the_previous_table(tmp_path, signum):
    old = constant_table(300)
    new = save(wave_table(), tmp_path)
    hold = HoldAfterFirstChunk()
    with ControllerPty(robot="snake5", table=old.encode(), line_filter=hold) as server:
        proc = _snakebot("upload", new, "--port", server.device)
        _wait_for(hold.seen.is_set, proc, "an upload chunk")
        _stop(proc, signum)
        with server.lock:
            server.line_filter = None
        assert server.active_table() == old.encode()  # not a byte of the new one active
        assert _port_is_free(server.device)
        again = _snakebot("upload", new, "--port", server.device)  # and the next one lands
        _, err = again.communicate(timeout=60)
        assert again.returncode == 0, err
        assert server.active_table() == new.read_bytes()
        assert server.error is None


# -- library store (the firmware under QEMU) ------------------------------------------------


@contextmanager
def _relay(device: str, hold_after: int) -> Iterator[tuple[str, threading.Event]]:
    """A pseudo-terminal of our own passing bytes to and from ``device``, until the host
    has sent ``hold_after`` bytes: then what the host sends is dropped (the event set),
    so a command is caught in the middle of its writes."""
    master, slave = os.openpty()
    tty.setraw(slave)
    far = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(far)
    held, stop = threading.Event(), threading.Event()

    def pump() -> None:
        sent = 0
        while not stop.is_set():
            ready, _, _ = select.select([master, far], [], [], 0.05)
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except OSError:
                    continue
                if fd == far:
                    os.write(master, data)
                elif sent < hold_after:
                    data = data[: hold_after - sent]
                    sent += len(data)
                    os.write(far, data)
                else:
                    held.set()

    thread = threading.Thread(target=pump, daemon=True)
    thread.start()
    try:
        yield os.ttyname(slave), held
    finally:
        stop.set()
        thread.join()
        for fd in (master, slave, far):
            os.close(fd)


@pytest.fixture(scope="module", params=["cm530", "qemu"])
def firmware(request, tmp_path_factory):
    """Each board's firmware: the CM-530 keeps its library in flash, QEMU's in RAM."""
    from firmware_support import booted

    with booted(request.param, tmp_path_factory.mktemp("bus")) as port:
        yield port


def _slot0(port: str) -> dict:
    import json

    listed = subprocess.run(
        [sys.executable, "-m", "snakebot", "library", "list", "--port", port, "--json"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert listed.returncode == 0, listed.stderr
    return json.loads(listed.stdout)["slots"][0]


@pytest.mark.qemu
@pytest.mark.serial  # QEMU behind a pty: its replies come late beside another worker
@pytest.mark.parametrize("signum", SIGNALS, ids=IDS)
def test_library_store_stopped_mid_slot_leaves_the_slot_as_it_was(firmware, tmp_path, signum):
    first = save(constant_table(400), tmp_path, "first.gait")
    stored = subprocess.run(
        [sys.executable, "-m", "snakebot", "library", "store", "0", first, "--port", firmware],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert stored.returncode == 0, stored.stderr
    before = _slot0(firmware)
    assert before["crc"] == zlib.crc32(first.read_bytes())
    new = save(wave_table(), tmp_path, "new.gait")  # 1.6 KB: many chunk writes
    with _relay(firmware, hold_after=600) as (port, held):
        proc = _snakebot("library", "store", "0", new, "--port", port)
        _wait_for(held.is_set, proc, "the library store under way")
        _stop(proc, signum)
    assert _slot0(firmware) == before  # as it was, not a part of the new table


# -- flash (the emulated bootloader) -------------------------------------------------------


@pytest.mark.parametrize("signum", SIGNALS, ids=IDS)
def test_flash_stopped_mid_image_exits_and_frees_the_port(tmp_path, signum):
    make_image(tmp_path / "fw.bin", 12_000)  # about 2 s at 57600 baud
    boot = Bootloader(silence_s=0.3)
    quick = {"SNAKEBOT_FLASH_QUIET_S": "0.05", "SNAKEBOT_FLASH_GO_TIMEOUT_S": "0.2"}
    with serve(boot, reset_after_s=0.3, pace=True) as server:
        proc = _snakebot(
            "flash", "--no-verify", "--no-library-backup", tmp_path / "fw.bin",
            "--port", server.device, env=quick,
        )  # fmt: skip
        _wait_for(lambda: boot.state == "receive", proc, "the image being sent")
        time.sleep(0.3)
        _stop(proc, signum)
        assert _port_is_free(server.device)
        assert server.error is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fw.bin"]  # nothing written


# -- robot calibrate -----------------------------------------------------------------------


def _read_until(proc: subprocess.Popen[bytes], text: bytes) -> bytes:
    assert proc.stdout is not None
    seen = b""
    deadline = time.monotonic() + 30
    while text not in seen:
        assert time.monotonic() < deadline, seen
        ready, _, _ = select.select([proc.stdout], [], [], 0.5)
        if ready:
            chunk = os.read(proc.stdout.fileno(), 4096)
            assert chunk, (seen, proc.communicate()[1])
            seen += chunk
    return seen


@pytest.mark.parametrize("signum", SIGNALS, ids=IDS)
def test_robot_calibrate_stopped_at_a_question_leaves_the_file_and_its_mode(tmp_path, signum):
    from importlib import resources

    mine = tmp_path / "mine.toml"
    mine.write_text(resources.files("snakebot.model.robots").joinpath("snake5.toml").read_text())
    mine.chmod(0o644)
    before = mine.read_bytes()
    proc = _snakebot("robot", "calibrate", mine, "--port", "sim://?robot=snake5")
    assert proc.stdin is not None
    _read_until(proc, b"then press Enter.")
    proc.stdin.write(b"\n")
    proc.stdin.flush()
    for _ in range(2):  # two joints' signs answered, the third asked: half a calibration
        _read_until(proc, b"seen from above?")
        proc.stdin.write(b"n\n")
        proc.stdin.flush()
    _read_until(proc, b"seen from above?")
    _stop(proc, signum)
    assert mine.read_bytes() == before and mine.stat().st_mode & 0o777 == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["mine.toml"]  # no temporary file left
