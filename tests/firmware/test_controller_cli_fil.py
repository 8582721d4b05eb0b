"""The controller commands against the real firmware image on both emulated boards: the
CM-530's image on the emulated STM32F103RE (its Dynamixel bus, USART1, on the chip's
clock) and the qemu board's build under QEMU (USART1 on a Unix socket), each driving the
emulated snake5 servos with its PC link (USART3) on a pseudo-terminal. Upload, play,
monitor, serpenoid and stop, byte for byte through the code that runs on the CM-530."""

from __future__ import annotations

import json
import time
import zlib

import pytest
from controller_cli_support import cli, cli_json, monitor_records, save, wave_table
from firmware_support import BOARDS, assert_healthy_bus, booted

pytestmark = pytest.mark.qemu


@pytest.fixture(scope="module", params=BOARDS)
def firmware(request, tmp_path_factory):
    with booted(request.param, tmp_path_factory.mktemp("bus")) as port:
        yield port


def test_upload_play_monitor_stop_on_the_firmware(firmware, tmp_path):
    path = save(wave_table(), tmp_path)
    crc = zlib.crc32(path.read_bytes())
    upload = cli("upload", path, "--port", firmware, "--json")
    assert upload.exit_code == 0, upload.output
    report = json.loads(upload.stdout)
    assert report["crc"] == f"0x{crc:08x}"
    assert report["attempts"] == 1, upload.stderr  # the retry's reason, if one was needed
    assert report["bytes"] == path.stat().st_size

    played = cli_json("play", "--port", firmware, "--speed", "2")
    assert played["state"] == "PLAYING" and played["speed"] == 2.0
    assert played["table"]["crc"] == f"0x{crc:08x}"

    time.sleep(0.2)  # a telemetry round over the emulated bus
    samples = monitor_records(firmware, duration=0.5)
    assert len(samples) >= 3
    for sample in samples:
        c = sample["controller"]
        assert c["state"] == "PLAYING" and c["error_flags"] == []
        assert c["table_crc"] == f"0x{crc:08x}"
        assert [s["id"] for s in sample["servos"]] == [10, 11, 15, 16]
    frames = [s["controller"]["play_frame"] for s in samples]
    assert len(set(frames)) > 1  # the firmware is playing through the table
    last = samples[-1]["servos"]
    assert all(s["voltage_v"] == 12.0 for s in last)
    assert_healthy_bus(
        samples[-1]["controller"]["bus_reads"], samples[-1]["controller"]["bus_timeouts"]
    )
    assert len({s["position"] for s in last}) > 1  # the servos follow the wave

    stopped = cli_json("stop", "--port", firmware)
    assert stopped["state"] == "IDLE"


def test_serpenoid_on_the_firmware(firmware, tmp_path):
    status = cli_json(
        "serpenoid",
        "--port",
        firmware,
        "--robot",
        "snake5",
        "-A",
        "25deg",
        "-w",
        "180deg",
        "-d",
        "90deg",
    )
    assert status["state"] == "SERPENOID" and status["joint_count"] == 4
    samples = monitor_records(firmware, duration=0.4)
    goals = [s["servos"][0]["goal"] for s in samples]
    assert len(set(goals)) > 1
    assert all(s["controller"]["state"] == "SERPENOID" for s in samples)
    assert cli_json("stop", "--port", firmware)["state"] == "IDLE"


def test_unknown_servos_and_bad_values_are_refused_by_the_firmware_side(firmware, tmp_path):
    snake5 = save(wave_table(), tmp_path, "snake5.gait")
    assert cli("upload", snake5, "--port", firmware).exit_code == 0  # the roster
    path = save(wave_table(ids=(1, 2, 3, 4)), tmp_path)
    result = cli("upload", path, "--port", firmware)
    # a table naming servos the controller's roster lacks is bad input, as everywhere (2)
    assert result.exit_code == 2 and "does not have" in result.stderr
    result = cli("play", "--port", firmware, "--speed", "8")
    assert result.exit_code == 2 and "--speed" in result.stderr
    assert "speed 8 is outside" in result.stderr
