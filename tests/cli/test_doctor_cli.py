"""`snakebot doctor` against emulated hardware: a servo bus (sim://, with the faults that
bring-up meets: two servos on one ID, a low supply, a long return delay, a one-wire echo),
the controller's real C logic on a pty (what `snakebot sim serve` serves), the emulated
bootloader, and the adapter's latency timer through a stand-in for /sys."""

from __future__ import annotations

import json

import pytest
from controller_cli_support import cli

from snakebot.link.bus.doctor import adapter
from snakebot.sim.bootloader import APP_BASE, Bootloader, BootloaderPty
from snakebot.sim.controller_pty import ControllerPty

pytestmark = pytest.mark.timeout(120)

QUICK = ("--ids", "0-5", "--bauds", "1000000")


def doctor(port: str, *args: str):
    result = cli("doctor", "--port", port, *args, "--json")
    return result, json.loads(result.stdout)


def verdicts(report: dict) -> dict[str, str]:
    return {c["name"]: c["verdict"] for c in report["checks"]}


def test_a_healthy_servo_bus_passes_every_check():
    result, report = doctor("sim://?ids=1,2,3", *QUICK)
    assert result.exit_code == 0, result.output
    v = verdicts(report)
    assert v["servo bus"] == "ok" and v["adapter"] == "skip"
    for i in (1, 2, 3):
        for what in ("", " return delay", " voltage", " temperature", " torque limit"):
            assert v[f"servo {i}{what}"] == "ok"
    assert report["ok"] is True


def test_two_servos_on_one_id_fail_with_the_fix():
    result, report = doctor("sim://?ids=1,1,2", *QUICK)
    assert result.exit_code == 1
    [conflict] = [c for c in report["checks"] if c["name"] == "servo 1"]
    assert conflict["verdict"] == "fail" and "share ID 1" in conflict["detail"]
    assert "set-id" in conflict["fix"]
    assert verdicts(report)["servo 2"] == "ok"


def test_a_one_wire_echo_is_not_taken_for_a_conflict():
    result, report = doctor("sim://?ids=1,2&echo=1", *QUICK)
    assert result.exit_code == 0, result.output
    assert set(verdicts(report).values()) <= {"ok", "skip"}


def test_a_low_supply_fails_against_the_servos_own_limits():
    result, report = doctor("sim://?ids=3&voltage=5", *QUICK)
    assert result.exit_code == 1
    [volts] = [c for c in report["checks"] if c["name"] == "servo 3 voltage"]
    assert volts["verdict"] == "fail" and "5 V, outside its limits 6-14 V" in volts["detail"]
    assert verdicts(report)["servo 3 alarm"] == "fail"


def test_a_return_delay_longer_than_assumed_warns():
    result, report = doctor("sim://?ids=4&return_delay=508", *QUICK)
    assert result.exit_code == 0  # a warning is not a failure
    [delay] = [c for c in report["checks"] if c["name"] == "servo 4 return delay"]
    assert delay["verdict"] == "warn" and "SNAKEBOT_RETURN_DELAY_US=508" in delay["fix"]


def test_nothing_on_the_bus_fails():
    result, report = doctor("sim://?ids=7&baud=57600", "--ids", "0-3", "--bauds", "1000000")
    assert result.exit_code == 1
    assert verdicts(report)["servo bus"] == "fail"


def test_the_controller_is_recognised_on_its_pc_link():
    with ControllerPty() as server:
        result, report = doctor(server.device)
    assert result.exit_code == 0, result.output
    v = verdicts(report)
    assert v["controller"] == v["controller model"] == v["controller firmware"] == "ok"
    assert "servo bus" not in v  # a controller answered: no bus scan


def test_the_human_output_marks_each_check():
    out = cli("doctor", "--port", "sim://?ids=1,1", *QUICK).stdout
    assert "FAIL  servo 1:" in out and "fix: connect the servos one at a time" in out


def test_the_bootloader_check_catches_it_and_starts_the_application(monkeypatch):
    monkeypatch.setenv("SNAKEBOT_FLASH_QUIET_S", "0.05")
    monkeypatch.setenv("SNAKEBOT_FLASH_GO_TIMEOUT_S", "0.2")
    boot = Bootloader()
    with BootloaderPty(boot, reset_after_s=0.3, pace=False) as server:
        result, report = doctor(server.device, "--bootloader")
        with server.lock:
            started = list(boot.started)
    assert result.exit_code == 0, result.output
    assert verdicts(report)["bootloader"] == "ok"
    assert started == [APP_BASE]


@pytest.mark.parametrize(("timer", "verdict"), [("1", "ok"), ("16", "warn"), (None, "skip")])
def test_the_ftdi_latency_timer(tmp_path, timer, verdict):
    device = tmp_path / "ttyUSB7"
    device.touch()
    sysfs = tmp_path / "sys"
    if timer is not None:
        (sysfs / "ttyUSB7").mkdir(parents=True)
        (sysfs / "ttyUSB7" / "latency_timer").write_text(timer + "\n")
    check = adapter(str(device), sysfs)
    assert check.verdict == verdict
    if verdict == "warn":
        assert f"echo 1 | sudo tee {sysfs}/ttyUSB7/latency_timer" in check.fix
        assert "snakebot bus scan --latency-timer 1" in check.fix
