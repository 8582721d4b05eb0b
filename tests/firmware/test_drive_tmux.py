"""`snakebot drive` on a real terminal (tmux) against `snakebot sim serve --robot snake5
--board qemu`: the screen shows the joint angles moving, arrow keys steer and change the
speed on screen and in the controller's registers, space stops, q stops the robot and quits
with the terminal restored. On QEMU, not the default board: this runs in the serial stage
beside three other workers, where the emulated CM-530 (most of a core at real time, in the
server's process) fell behind and the screen did not follow in time."""

from __future__ import annotations

import contextlib
import math
import re
import shutil
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from firmware_support import build_firmware

from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.drive import SPEED_STEP, STEER_STEP

pytestmark = [pytest.mark.qemu, pytest.mark.slow, pytest.mark.serial]

SNAKEBOT = str(Path(sys.executable).with_name("snakebot"))
SCREEN_TIMEOUT_S = 20.0
ROW = re.compile(r"^\s*(phi\d)\s+(\d+)\s+([-+]\d+\.\d)\s+([-+]\d+\.\d)\s+([-+]\d+\.\d)\s+(\S.*)$")


@pytest.fixture(scope="module")
def served() -> Iterator[str]:
    """`snakebot sim serve --robot snake5` running; yields its PC link."""
    build_firmware()
    server = subprocess.Popen(
        [SNAKEBOT, "sim", "serve", "--board", "qemu", "--robot", "snake5", "--world", "kinematic"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        pc_link = None
        assert server.stdout is not None
        for line in server.stdout:
            found = re.search(r"PC link \(USART3\): (\S+)", line)
            if found:
                pc_link = found.group(1)
                break
        assert pc_link, "sim serve printed no PC link"
        yield pc_link
    finally:
        server.send_signal(signal.SIGINT)
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()


class Tmux:
    """One detached tmux session on a private server."""

    def __init__(self, command: str) -> None:
        if shutil.which("tmux") is None:
            pytest.fail("tmux missing: run `make setup`")
        self.socket = f"snakebot-drive-{uuid.uuid4().hex[:8]}"
        self._tmux("new-session", "-d", "-s", "drive", "-x", "120", "-y", "30", command)

    def _tmux(self, *args: str) -> str:
        done = subprocess.run(
            ["tmux", "-L", self.socket, *args], capture_output=True, text=True, check=True
        )
        return done.stdout

    def keys(self, *keys: str) -> None:
        self._tmux("send-keys", "-t", "drive", *keys)

    def screen(self) -> str:
        return self._tmux("capture-pane", "-p", "-t", "drive")

    def wait_for(self, seen: Callable[[str], bool], what: str) -> str:
        deadline = time.monotonic() + SCREEN_TIMEOUT_S
        while time.monotonic() < deadline:
            text = self.screen()
            if seen(text):
                return text
            time.sleep(0.1)
        pytest.fail(f"the screen never showed {what}:\n{self.screen()}")

    def close(self) -> None:
        with contextlib.suppress(subprocess.CalledProcessError):
            self._tmux("kill-server")


def joints(screen: str) -> dict[str, float]:
    """Joint name -> the angle column (present position, degrees) on the screen."""
    rows = (ROW.match(line) for line in screen.splitlines())
    return {m.group(1): float(m.group(4)) for m in rows if m}


def test_drive_on_a_terminal(served):
    command = f"{SNAKEBOT} drive --port {served} --robot snake5"
    tmux = Tmux(f"{command}; echo EXIT=$?; sleep 60")
    try:
        first = tmux.wait_for(lambda s: "State SERPENOID" in s and len(joints(s)) == 4, "4 joints")
        assert set(joints(first)) == {"phi1", "phi2", "phi3", "phi4"}
        assert "steering +0.0 deg" in first and "speed 1.00x" in first
        # the wave moves the joints: the angles on screen change
        tmux.wait_for(lambda s: joints(s) and joints(s) != joints(first), "the joints moving")

        tmux.keys("Left", "Left", "Right", "Left")
        steered = f"steering {2 * math.degrees(STEER_STEP):+.1f} deg"
        tmux.wait_for(lambda s: steered in s, steered)
        tmux.keys("Up")
        tmux.wait_for(lambda s: f"speed {1 + SPEED_STEP:.2f}x" in s, "the new speed")
        tmux.keys("Space")
        tmux.wait_for(lambda s: "State IDLE" in s and "(stopped)" in s, "stopped")
        time.sleep(0.5)  # the servos finish the way to their last goal...
        held = joints(tmux.screen())
        time.sleep(0.6)  # ...and then hold it
        assert joints(tmux.screen()) == held
        tmux.keys("Space")
        tmux.wait_for(lambda s: "State SERPENOID" in s and "(started)" in s, "started again")
        tmux.keys("q")
        tmux.wait_for(lambda s: "EXIT=0" in s, "drive quitting cleanly")
    finally:
        tmux.close()

    with ControllerClient.open(served) as ctl:
        regs = ctl.read("State", "Steering Offset", "Speed Scale")
    steering = ctl.table.register("Steering Offset")
    assert regs["State"] == ctl.table.enums["State"]["IDLE"]  # q stopped the robot
    assert regs["Steering Offset"] == 2 * steering.from_units(STEER_STEP, "rad")
    speed = ctl.table.register("Speed Scale").to_units(regs["Speed Scale"], "x")
    assert speed == pytest.approx(1 + SPEED_STEP)
