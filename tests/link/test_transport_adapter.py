"""The reply-latency allowance comes from the adapter: an FTDI adapter's latency timer as
Linux shows it, zero for a pseudo-terminal and the emulator, the configured default for
anything that cannot tell; setting the timer explains the permission it needs."""

from __future__ import annotations

import os
import pty
from pathlib import Path

import pytest
from click.testing import CliRunner

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli import main
from snakebot.link.transport import DxlClient, PortError, adapter, open_port, settings
from snakebot.link.transport.timing import PROGRAM_MARGIN_S, USB_LATENCY_S


@pytest.fixture
def no_env(monkeypatch):
    monkeypatch.delenv(settings.ENV_LATENCY_MS, raising=False)
    monkeypatch.delenv(settings.ENV_MARGIN_MS, raising=False)
    return monkeypatch


@pytest.fixture
def ftdi(tmp_path):
    """A device ttyUSB7 whose sysfs entry shows a latency timer of 16 ms."""
    device = tmp_path / "ttyUSB7"
    device.touch()
    sysfs = tmp_path / "sys"
    (sysfs / "ttyUSB7").mkdir(parents=True)
    (sysfs / "ttyUSB7" / "latency_timer").write_text("16\n")
    return str(device), sysfs


def test_an_ftdi_adapter_reports_its_latency_timer(ftdi):
    device, sysfs = ftdi
    assert adapter.latency_timer_ms(device, sysfs) == 16
    (sysfs / "ttyUSB7" / "latency_timer").write_text("1\n")
    assert adapter.latency_timer_ms(device, sysfs) == 1


def test_a_device_without_a_timer_or_a_url_reports_none(tmp_path):
    device = tmp_path / "ttyS0"
    device.touch()
    assert adapter.latency_timer_ms(str(device), tmp_path) is None
    assert adapter.latency_timer_ms("sim://?ids=1", tmp_path) is None


def test_the_emulator_and_a_pty_hold_nothing_so_the_client_waits_for_no_adapter(
    no_env, monkeypatch
):
    monkeypatch.delenv(settings.ENV_MARGIN_MS, raising=False)
    with DxlClient("sim://?ids=1") as bus:
        assert bus.timing.latency_s == 0.0
    controller, device = pty.openpty()
    try:
        name = os.ttyname(device)
        with open_port(name, 1_000_000, timeout=0) as port, DxlClient(port) as bus:
            assert bus.timing.latency_s == 0.0
            # ...but the program there may be descheduled: replies get a program's slack
            assert bus.timing.margin_s == PROGRAM_MARGIN_S
    finally:
        os.close(controller)
        os.close(device)


def test_an_adapter_that_cannot_tell_gets_the_default_and_the_environment_wins(no_env):
    with DxlClient("loop://") as bus:
        assert bus.timing.latency_s == USB_LATENCY_S
    no_env.setenv(settings.ENV_LATENCY_MS, "3")
    with DxlClient("sim://?ids=1") as bus:
        assert bus.timing.latency_s == 0.003


def test_setting_the_timer_writes_sysfs_or_explains_the_permission(ftdi, monkeypatch):
    device, sysfs = ftdi
    adapter.set_latency_timer(device, 1, sysfs)
    assert adapter.latency_timer_ms(device, sysfs) == 1

    def refused(self, text):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "write_text", refused)  # as for a user without root
    with pytest.raises(PortError, match=r"needs root .*sudo tee .*udev rule"):
        adapter.set_latency_timer(device, 1, sysfs)


def test_setting_the_timer_of_something_else_is_refused_as_bad_input():
    result = CliRunner().invoke(
        main, ["bus", "scan", "-p", "sim://?ids=1", "--ids", "1", "--latency-timer", "1"]
    )
    assert result.exit_code == 2
    assert "no latency timer to set" in result.output
