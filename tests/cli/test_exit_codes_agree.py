"""The same refusal exits the same way from every command (issue #28): a table outside
the robot's limits is bad input (2) from `upload` and `library store` alike; a command
refused because of the controller's state (SAFE) is a runtime failure (1), from `play`
as from `serpenoid`. The controller's C logic on a pty (controller_cli_support)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from controller_cli_support import cli, cli_json, constant_table, save, wave_table
from py_library import PyStore

from snakebot.core import lib
from snakebot.formats.gaittable import GaitTable
from snakebot.link.controller import State
from snakebot.model.robots import load_robot
from snakebot.sim.controller_pty import ControllerDevice, ControllerPty

pytestmark = pytest.mark.timeout(120)


@pytest.fixture
def with_library():
    """A snake5 controller with a gait library (a Python store: tests/support/py_library.py)."""
    store = PyStore()
    server = ControllerPty(robot="snake5")
    server.device_logic = ControllerDevice(server.bus)
    lib.ctl_set_library(server.device_logic.d, store.c)
    with server:
        yield server.device
        assert server.error is None, server.error


def test_a_table_outside_the_robot_limits_is_bad_input_for_upload_and_library_store(
    with_library, tmp_path
):
    port = with_library
    robot = load_robot("snake5")
    assert cli_json("limits", "set", "snake5", "--port", port)["state"] == "VERIFIED"
    wave = wave_table(robot.servo_ids)
    frames = np.array(wave.frames)
    frames[0], frames[1] = 896, 198  # beyond snake5's limits, within the servo's
    wide = GaitTable(wave.joint_ids, 20, True, ((24, 1000),) * len(wave.joint_ids), frames, {})
    path = save(wide, tmp_path, "wide.gait")

    upload = cli("upload", path, "--port", port)
    store = cli("library", "store", "0", str(path), "--port", port)

    for result in (upload, store):
        assert "OUTSIDE_ROBOT_LIMITS" in result.stderr, result.output
        assert result.stderr.startswith("error: ") and "Traceback" not in result.output
    assert (upload.exit_code, store.exit_code) == (2, 2)


def test_the_safe_state_is_a_runtime_failure_for_play_and_serpenoid():
    # the table names servo 16, which is not on the bus: telemetry misses -> BUS_LOSS
    with ControllerPty(servo_ids=(10, 11, 15), table=constant_table(512).encode()) as server:
        deadline = time.monotonic() + 5
        while server.state() != State.SAFE and time.monotonic() < deadline:
            time.sleep(0.02)
        assert server.state() == State.SAFE
        play = cli("play", "--port", server.device)
        serpenoid = cli("serpenoid", "-A", "0.2", "-w", "1", "-d", "1", "--port", server.device)
    for result in (play, serpenoid):
        assert "safe state" in result.stderr, result.output
    assert (play.exit_code, serpenoid.exit_code) == (1, 1)
