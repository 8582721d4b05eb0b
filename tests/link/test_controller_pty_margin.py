"""A controller on a pseudo-terminal is a program on this host (the emulated one under
QEMU), which a busy host can deschedule for far longer than a UART stalls: the controller
client gives it timing.PROGRAM_MARGIN_S of slack by default, and a real port keeps the
host margin. The keyword and SNAKEBOT_MARGIN_MS still win."""

from __future__ import annotations

import os
import time

import pytest

from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.errors import ControllerLinkError
from snakebot.link.transport import settings, timing
from snakebot.link.transport.ports import is_pseudo_terminal
from snakebot.sim.controller_pty import ControllerPty

STALL_S = 0.1
"""How long the emulated controller is descheduled before each answer: far beyond the
host margin plus the wire time, well inside the pseudo-terminal margin."""

LONG_STALL_S = 1.5
"""The stall the host-margin half of the test uses: a reply that waits 0.1 s would still be
taken if this test's own process were descheduled longer than that between its write and its
first look for the reply (it happened on a loaded CI machine), so that half stalls far
longer than any such pause."""


@pytest.fixture(autouse=True)
def no_margin_setting(monkeypatch):
    monkeypatch.delenv(settings.ENV_MARGIN_MS, raising=False)


def stalling(seconds: float):
    def stall(index: int, packet: bytes) -> bytes:
        time.sleep(seconds)
        return packet

    return stall


@pytest.fixture
def stalling_controller():
    """The controller's device logic on a pty, answering every packet STALL_S late."""

    with ControllerPty(robot=None, line_filter=stalling(STALL_S)) as server:
        yield server
        assert server.error is None, server.error


def test_a_pseudo_terminal_is_told_from_other_ports(tmp_path):
    primary, secondary = os.openpty()
    try:
        device = os.ttyname(secondary)
        link = tmp_path / "ttyCTL"
        link.symlink_to(device)
        regular = tmp_path / "file"
        regular.write_bytes(b"")
        assert is_pseudo_terminal(device)
        assert is_pseudo_terminal(str(link))  # `sim serve --link`-style symlinks too
        for other in ("/dev/null", str(regular), str(tmp_path / "absent"), "loop://"):
            assert not is_pseudo_terminal(other), other
    finally:
        os.close(primary)
        os.close(secondary)


def test_the_controller_on_a_pty_gets_the_program_margin_unless_told(
    stalling_controller, monkeypatch
):
    device = stalling_controller.device
    with ControllerClient.open(device) as ctl:
        assert ctl.link.timing.margin_s == timing.PROGRAM_MARGIN_S
    with ControllerClient.open(device, margin_s=0.05) as ctl:
        assert ctl.link.timing.margin_s == 0.05
    monkeypatch.setenv(settings.ENV_MARGIN_MS, "20")
    with ControllerClient.open(device) as ctl:
        assert ctl.link.timing.margin_s == pytest.approx(0.02)
    monkeypatch.delenv(settings.ENV_MARGIN_MS)
    with ControllerClient.open("loop://") as ctl:  # not a pty: the host margin
        assert ctl.link.timing.margin_s == timing.HOST_MARGIN_S


def test_a_descheduled_emulated_controller_still_answers_the_first_try(stalling_controller):
    device = stalling_controller.device
    with ControllerClient.open(device, retries=0) as ctl:
        assert ctl.read("State")["State"] == ctl.table.enums["State"]["IDLE"]
    # what the host margin alone makes of a stall
    with stalling_controller.lock:
        stalling_controller.line_filter = stalling(LONG_STALL_S)
    with ControllerClient.open(device, retries=0, margin_s=timing.HOST_MARGIN_S) as ctl:
        with pytest.raises(ControllerLinkError, match="did not answer"):
            ctl.read("State")
