"""`snakebot drive` on a real terminal (tmux) against `snakebot sim serve --robot snake5
--board qemu`: the screen shows the joint angles moving, arrow keys steer and change the
speed on screen and in the controller's registers, space stops, q stops the robot and quits
with the terminal restored. On QEMU, not the default board: this runs in the serial stage
beside three other workers, where the emulated CM-530 (most of a core at real time, in the
server's process) fell behind and the screen did not follow in time."""

from __future__ import annotations

import math
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from firmware_support import build_firmware
from tmux_support import SCREEN_TIMEOUT_S, Tmux, joints

from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.drive import SPEED_STEP, STEER_STEP

pytestmark = [pytest.mark.qemu, pytest.mark.slow, pytest.mark.serial]

SNAKEBOT = str(Path(sys.executable).with_name("snakebot"))
HOLD_S = 0.6
"""A stopped robot's joints show the same angles this long: they hold their goals."""


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
        # the servos finish the way to their last goal (loaded ones, at the wave's last
        # Moving Speed, take up to a second or two), and then hold it
        deadline = time.monotonic() + SCREEN_TIMEOUT_S
        held = joints(tmux.screen())
        while True:
            time.sleep(HOLD_S)
            now = joints(tmux.screen())
            if now == held:
                break
            assert time.monotonic() < deadline, ("the joints never came to rest", held, now)
            held = now
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
