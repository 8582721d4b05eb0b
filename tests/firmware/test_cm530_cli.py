"""The controller commands against the exact CM-530 image on the emulated STM32F103RE
(`snakebot sim serve --board cm530` in process): upload and play a gait on the snake5's
emulated servos, watch it with monitor, stop it; the servos' goals are what the firmware
sent through USART1 and the bus direction pins."""

from __future__ import annotations

import json
import select
import signal
import subprocess
import sys
import time
import zlib

import pytest
from controller_cli_support import cli, cli_json, monitor_records, save, wave_table
from firmware_support import assert_healthy_bus

from snakebot.firmware import image as firmware_image
from snakebot.sim.serve import EmulatedRobot

pytest.importorskip("unicorn")
pytestmark = [pytest.mark.slow, pytest.mark.serial]  # real time on a pty

# The emulated chip runs in this process, in Python where it touches a peripheral: on a
# loaded machine it may fall below real time while the bus is busy (it then slows its
# clock rather than pile up a backlog), so its replies get a wider margin than a board's.
SLOW_HOST = {"SNAKEBOT_MARGIN_MS": "3000"}


@pytest.fixture(scope="module")
def robot():
    if not firmware_image("cm530", "firmware.elf").is_file():
        pytest.skip("build/cm530/firmware.elf is not built: make firmware")
    with EmulatedRobot("snake5", board="cm530") as emulated:
        yield emulated


def test_upload_play_monitor_stop_on_the_cm530_image(robot, tmp_path):
    port = robot.info.pc_link
    path = save(wave_table(), tmp_path)
    crc = zlib.crc32(path.read_bytes())
    upload = cli("upload", path, "--port", port, "--json", env=SLOW_HOST)
    assert upload.exit_code == 0, upload.output
    assert json.loads(upload.stdout)["crc"] == f"0x{crc:08x}"

    played = cli_json("play", "--port", port, "--speed", "2", env=SLOW_HOST)
    assert played["state"] == "PLAYING"
    time.sleep(0.3)
    samples = monitor_records(port, duration=1.0, env=SLOW_HOST)
    assert len(samples) >= 3
    frames = [s["controller"]["play_frame"] for s in samples]
    assert len(set(frames)) > 1  # the firmware plays through the table
    last = samples[-1]
    assert [s["id"] for s in last["servos"]] == [10, 11, 15, 16]
    assert_healthy_bus(last["controller"]["bus_reads"], last["controller"]["bus_timeouts"])
    with robot.lock:
        goals = [robot.servo(i).regs.get("Goal Position") for i in (10, 11, 15, 16)]
        stats = robot._mcu.board.bus_stats  # noqa: SLF001 - what crossed the bus buffer
    assert len(set(goals)) > 1  # the servos got the wave's goals over the emulated wire
    assert stats.sent > 100 and stats.blocked == 0 and stats.received > 0
    assert cli_json("stop", "--port", port, env=SLOW_HOST)["state"] == "IDLE"


def test_sim_serve_board_cm530_answers_and_stops_on_sigterm():
    if not firmware_image("cm530", "firmware.elf").is_file():
        pytest.skip("build/cm530/firmware.elf is not built: make firmware")
    proc = subprocess.Popen(
        [sys.executable, "-m", "snakebot", "sim", "serve", "--board", "cm530", "--json"]
        + ["--report", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], 60)
        assert ready, "no output from `snakebot sim serve --board cm530`"
        first = json.loads(proc.stdout.readline())
        assert first["event"] == "serving" and first["servo_ids"] == [10, 11, 15, 16]
        result = cli(
            "doctor", "--port", first["pc_link"], "--board", "cm530", "--json", env=SLOW_HOST
        )
        assert json.loads(result.stdout)["board"] == "cm530", result.output
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=20)
        assert proc.returncode == 143, err
        assert "Traceback" not in err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
