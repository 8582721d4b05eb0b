"""Opening ports by path or URL, and the errors a person sees when that fails."""

from __future__ import annotations

import errno
import os
import socket
import subprocess
import sys
import tty

import pytest
import serial

from snakebot.errors import SnakebotError
from snakebot.link.transport import DxlClient, PortError, open_port, register_handler_package
from snakebot.link.transport.ports import _explain


def test_missing_device_names_the_port_and_the_fix():
    with pytest.raises(PortError) as info:
        open_port("/dev/ttySNAKEBOT-missing", 1_000_000)
    assert info.value.port == "/dev/ttySNAKEBOT-missing"
    assert "/dev/ttySNAKEBOT-missing does not exist" in str(info.value)
    assert "plugged in" in str(info.value)
    assert isinstance(info.value, SnakebotError)


def test_client_reports_a_missing_port_the_same_way():
    with pytest.raises(PortError, match="does not exist"):
        DxlClient("/dev/ttySNAKEBOT-missing")


@pytest.mark.skipif(os.geteuid() == 0, reason="root may open any file")
def test_unreadable_device_suggests_the_dialout_group(tmp_path):
    device = tmp_path / "ttyLOCKED"
    device.touch(mode=0)
    with pytest.raises(PortError, match="no permission"):
        open_port(str(device))


def test_permission_error_from_pyserial_is_explained():
    exc = serial.SerialException(
        errno.EACCES, "could not open port /dev/ttyUSB0: [Errno 13] Permission denied"
    )
    text = _explain("/dev/ttyUSB0", exc)
    assert "no permission to open serial port /dev/ttyUSB0" in text
    if sys.platform.startswith("linux"):
        assert "dialout" in text


def test_unknown_url_scheme():
    with pytest.raises(PortError, match="unknown port scheme nosuch://"):
        open_port("nosuch://robot")


def test_nothing_listening_on_socket_url():
    with socket.socket() as probe:  # find a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        free = probe.getsockname()[1]
    with pytest.raises(PortError, match="nothing is listening"):
        open_port(f"socket://127.0.0.1:{free}")


def test_opens_a_pseudo_terminal_at_the_requested_baud():
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        port = open_port(os.ttyname(slave), 57600, timeout=0)
        try:
            assert (port.baudrate, port.timeout) == (57600, 0)
            port.write(b"\xff\xff")
            assert os.read(master, 2) == b"\xff\xff"
        finally:
            port.close()
    finally:
        os.close(master)
        os.close(slave)


def test_registered_handler_package_serves_its_scheme(tmp_path, monkeypatch):
    # How sim:// reaches every port option: a package with protocol_<scheme> modules.
    package = tmp_path / "extra_handlers"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "protocol_echoloop.py").write_text(
        "from serial.urlhandler.protocol_loop import Serial as _Loop\n"
        "class Serial(_Loop):\n"
        "    def from_url(self, url):\n"
        "        return super().from_url('loop://')\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(serial, "protocol_handler_packages", list(serial.protocol_handler_packages))
    with pytest.raises(PortError):
        open_port("echoloop://")
    register_handler_package("extra_handlers")
    register_handler_package("extra_handlers")
    assert serial.protocol_handler_packages.count("extra_handlers") == 1
    port = open_port("echoloop://", 115200, timeout=0.5)
    try:
        port.write(b"abc")
        assert port.read(3) == b"abc"
    finally:
        port.close()


def test_sim_urls_open_without_importing_the_emulator_first():
    # A fresh interpreter, so nothing else in the test session has imported snakebot.sim.
    code = (
        "import sys\n"
        "from snakebot.link.transport import DxlClient\n"
        "assert 'snakebot.sim' not in sys.modules\n"
        "with DxlClient('sim://?robot=snake5') as c:\n"
        "    print(c.model_number(10))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert out.stdout.strip() == "12"  # an AX-12A answered on the emulated bus
