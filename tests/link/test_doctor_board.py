"""`snakebot doctor` names the board the controller's firmware was built for (the Board
field of the Program page) and checks it against --board and against the port: the real
QEMU image answers `qemu`, the controller's logic run on the host names none, and a QEMU
image answering on a hardware port is a warning that says to flash the CM-530's."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from controller_cli_support import cli
from firmware_support import booted

from snakebot.core import lib
from snakebot.link.bus.doctor import board, board_names, on_hardware
from snakebot.sim.controller_pty import ControllerPty

pytestmark = pytest.mark.timeout(120)


def doctor(port: str, *args: str) -> tuple[int, dict]:
    result = cli("doctor", "--port", port, *args, "--json")
    return result.exit_code, json.loads(result.stdout)


def board_check(report: dict) -> dict:
    [check] = [c for c in report["checks"] if c["name"] == "controller board"]
    return check


def test_the_boards_come_from_the_board_enum():
    assert board_names() == ["cm530", "qemu"]


def test_the_logic_on_the_host_names_no_board():
    with ControllerPty() as server:
        code, report = doctor(server.device)
        wrong, strict = doctor(server.device, "--board", "cm530")
    assert code == 0 and report["board"] is None
    assert board_check(report)["verdict"] == "ok"
    assert "none named" in board_check(report)["detail"]
    assert wrong == 1 and board_check(strict)["verdict"] == "fail"
    assert "snakebot flash --port" in board_check(strict)["fix"]


def test_the_board_the_controller_names_is_checked_against_the_expected_one():
    with ControllerPty() as server:
        lib.ctl_set_board(server.device_logic.d, lib.CTL_BOARD_CM530)
        code, report = doctor(server.device, "--board", "cm530")
        wrong, other = doctor(server.device, "--board", "qemu")
        human = cli("doctor", "--port", server.device).stdout
    assert code == 0 and report["board"] == "cm530"
    assert board_check(report) == {
        "name": "controller board",
        "verdict": "ok",
        "detail": "cm530",
        "fix": "",
    }
    assert wrong == 1 and other["board"] == "cm530"
    assert board_check(other)["detail"] == "cm530, not the qemu expected"
    assert "ok    controller board: cm530" in human


def fake_tty_sysfs(tmp_path: Path, port: str, hardware: bool) -> Path:
    """A stand-in for /sys/class/tty where ``port`` is (or is not) backed by hardware."""
    sysfs = tmp_path / "tty"
    entry = sysfs / Path(os.path.realpath(port)).name
    entry.mkdir(parents=True)
    if hardware:
        (entry / "device").mkdir()
    return sysfs


@pytest.mark.parametrize("hardware", [True, False])
def test_a_qemu_image_on_a_hardware_port_is_a_warning(tmp_path, hardware):
    port = tmp_path / "ttyUSB3"
    port.touch()
    sysfs = fake_tty_sysfs(tmp_path, str(port), hardware)
    assert on_hardware(str(port), sysfs) is hardware
    check = board(str(port), "QEMU", sysfs=sysfs)
    if hardware:
        assert check.verdict == "warn" and "ttyUSB3, a hardware port" in check.detail
        assert check.fix.startswith("flash the cm530 image")
        assert f"snakebot flash --port {port}" in check.fix
    else:
        assert (check.verdict, check.detail) == ("ok", "qemu")
    # the CM-530's image is at home on hardware
    assert board(str(port), "CM530", sysfs=sysfs).verdict == "ok"


def test_urls_are_never_hardware(tmp_path):
    assert not on_hardware("sim://?ids=1", tmp_path)


@pytest.mark.qemu
@pytest.mark.serial
def test_the_qemu_image_names_its_board(tmp_path):
    with booted("qemu", tmp_path) as port:
        code, report = doctor(port, "--board", "qemu")
        wrong, strict = doctor(port, "--board", "cm530")
    assert code == 0, report
    assert report["board"] == "qemu" and board_check(report)["detail"] == "qemu"
    assert wrong == 1 and board_check(strict)["verdict"] == "fail"
    assert board_check(strict)["fix"].startswith("flash the cm530 image")
