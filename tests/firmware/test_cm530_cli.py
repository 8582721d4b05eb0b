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


def test_the_bus_gets_each_packet_whole_at_its_first_bytes_start(robot, tmp_path):
    # the board hands the bus what USART1 sent back to back in one write (the bus's work
    # per packet, not per byte): the same bytes, from the first one's start bit, at the
    # programmed rate, a whole Dynamixel packet a write while the firmware plays, also
    # where a packet spans the end of the thread's step
    port = robot.info.pc_link
    cli_json("upload", save(wave_table(), tmp_path), "--port", port, env=SLOW_HOST)
    assert cli_json("play", "--port", port, env=SLOW_HOST)["state"] == "PLAYING"
    sent: list[tuple[int, float, float]] = []  # (byte, start, end) as USART1 sent them
    writes: list[tuple[float, bytes]] = []  # (bus time, bytes) as the bus got them
    with robot.lock:
        board = robot._mcu.board  # noqa: SLF001 - taps on the board's two sides
        usart1, bus = board.mcu.usart1, board.bus
        on_tx, master_write = usart1.on_tx, bus.master_write
        usart1.on_tx = lambda b, s, e, baud: (sent.append((b, s, e)), on_tx(b, s, e, baud))
        bus.master_write = lambda data: (writes.append((bus.now, bytes(data))), master_write(data))
    time.sleep(0.5)
    with robot.lock:
        usart1.on_tx, bus.master_write = on_tx, master_write
        blocked = board.bus_stats.blocked
    assert cli_json("stop", "--port", port, env=SLOW_HOST)["state"] == "IDLE"
    assert blocked == 0 and len(writes) >= 20
    writes = writes[1:]  # the first may hold bytes sent before the taps
    sent = sent[[start for _, start, _ in sent].index(writes[0][0]) :]
    given = b"".join(data for _, data in writes)
    assert given == bytes(b for b, _, _ in sent[: len(given)])  # the same bytes, in order
    first = whole = 0
    for t, data in writes:
        assert t == sent[first][1]  # the bus's clock at the first byte's start bit
        for k in range(first + 1, first + len(data)):
            assert sent[k][1] == sent[k - 1][2]  # back to back
        whole += data[:2] == b"\xff\xff" and data[3] + 4 == len(data)
        first += len(data)
    assert whole >= 0.9 * len(writes)  # a packet in one write (a bus event inside one splits it)


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
