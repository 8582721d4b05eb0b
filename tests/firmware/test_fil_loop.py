"""The full loop on the real firmware: a serpenoid table for snake5 uploaded and played
through the `snakebot` commands on the firmware's PC link, the emulated servos following
the firmware's bus master, and the emulated world's body advancing as the table predicts
(in QEMU, whose emulator costs the QEMU stage a third of the CPU the emulated CM-530
does: the same chain on the CM-530's image is the demo's test, tests/firmware/test_demo.py,
upload and play on both boards test_controller_cli_fil.py); and an overload injected in a
servo putting the player in its safe state, which `snakebot monitor --json` reports, on
both boards.

(Uploads cut off after the k-th chunk, corrupted chunks, garbage on the PC link and failed
commits are tested in test_controller_cli_upload.py, test_controller_cli_fil.py and
test_firmware_fil.py.)"""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest
from click.testing import CliRunner
from firmware_support import BOARDS, build_firmware, emulated_robot

from snakebot.cli import main
from snakebot.facts.boards import CONTROL_TICK_MS
from snakebot.formats.gaittable import write_gait
from snakebot.model.gait import serpenoid
from snakebot.model.robots import load_robot
from snakebot.sim.serve import EmulatedRobot
from snakebot.workflows.demo import compare, table_phase

pytestmark = [pytest.mark.qemu, pytest.mark.slow]

WARMUP_CYCLES = 1
CYCLES = 2
CONTROL_TICK_S = CONTROL_TICK_MS / 1000  # the firmware's control tick
PLAY_TIMEOUT_S = 60.0
OVERLOAD_TORQUE_NM = 5.0  # well above an AX-12A's 1.5 N m stall torque
ALARM_TIMEOUT_S = 10.0


def cli(*args: object) -> str:
    result = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return result.stdout


@pytest.fixture(scope="module")
def robot():
    build_firmware()
    with EmulatedRobot("snake5", board="qemu") as emulated:
        yield emulated


@pytest.fixture(params=BOARDS)
def any_board(request, robot):
    """The emulated robot on each board (the module's QEMU one for the qemu board)."""
    if request.param == "qemu":
        yield robot
        return
    with emulated_robot("snake5", request.param) as emulated:
        yield emulated


@pytest.fixture(scope="module")
def gait():
    return serpenoid(
        load_robot("snake5"), math.radians(30), math.pi, math.radians(90), cycles=1, loop=True
    )


def played_cycles(robot: EmulatedRobot, angles: np.ndarray) -> float:
    t, goals = robot.goals()
    if len(t) < 2 or not np.ptp(goals, axis=0).any():
        return 0.0
    _, phase = table_phase(angles, t, robot.robot.ticks_to_angles(goals))
    return phase[-1] / len(angles)


def test_upload_play_and_the_snake_advances_as_predicted(robot, gait, tmp_path):
    """Upload and play through the CLI; the servos move; the world's body goes where the
    table predicts, within a tolerance derived from the measured servo lag.

    Why a tolerance, and how large: the world integrates the same kinematic model as the
    prediction, from the servos' positions instead of the table's angles, so every bit of
    difference comes from the joints not being exactly where the table says: servo lag.
    The firmware sends a goal every control tick with the speed that reaches it by
    the next tick, so a servo trails its goals by about one tick. The test measures that:
    the lag (the delay that best fits the measured joint angles to the goals the firmware
    sent, least squares over the measured cycles) and the residual tracking error left
    after removing it. The tolerance is then
        |D(lag) - D(0)|  +  2 * S * residual_max
    where D(d) is the predicted displacement over the measured cycles with every joint
    delayed by d (the lag's own effect, computed on the model), and S the body's
    sensitivity to a joint-path error: displacement change per radian of largest joint
    deviation, taken as the worst over delays of 10, 20 and 40 ms (a delay is the shape a
    servo's lag has); the factor 2 covers residual errors of other shapes. The assertions
    also check that the tolerance is small beside the distance travelled (so the test can
    fail), that the lag is what the firmware's design allows (a few ticks, not a stall),
    and that the residual is small (the servos really track the gait)."""
    path = tmp_path / "walk.gait"
    table = gait.gait_table()
    write_gait(path, table)
    port = robot.info.pc_link
    report = json.loads(cli("upload", path, "--port", port, "--new-servos", "--json"))
    assert report["bytes"] == path.stat().st_size
    before = robot.positions()
    played = json.loads(cli("play", "--port", port, "--loop", "--json"))
    assert played["state"] == "PLAYING"

    angles = robot.robot.ticks_to_angles(table.frames.astype(float))
    end = time.monotonic() + PLAY_TIMEOUT_S
    while played_cycles(robot, angles) < WARMUP_CYCLES + CYCLES + 0.05:
        assert time.monotonic() < end, "the firmware did not play the cycles in time"
        time.sleep(0.2)
    stopped = json.loads(cli("stop", "--port", port, "--json"))
    assert stopped["state"] == "IDLE"

    record = robot.record()
    goal_t, goal_ticks = robot.goals()
    c = compare(robot.robot, table, record, goal_t, goal_ticks, WARMUP_CYCLES, CYCLES)

    # The servos moved through the table's whole range, each joint.
    lo, hi = np.degrees(c.joints.measured.min(0)), np.degrees(c.joints.measured.max(0))
    want_lo, want_hi = np.degrees(angles.min(0)), np.degrees(angles.max(0))
    assert (np.abs(lo - want_lo) < 3).all() and (np.abs(hi - want_hi) < 3).all(), (lo, hi)
    assert before != robot.positions()

    # The servos track: lag a few control ticks at most, little error beyond it.
    assert 0 <= c.lag_s <= 5 * CONTROL_TICK_S, c.as_dict()
    assert math.degrees(c.residual_max_rad) < 5, c.as_dict()

    # The body advanced, forward, as predicted within the lag-derived tolerance; beyond
    # it only if the host disturbed the firmware's pace (INVALID: a busy machine).
    assert c.emulated["dx"] > 0.5 * c.predicted["dx"] > 0
    assert c.tolerance_m < 0.25 * c.predicted["distance"], c.as_dict()
    assert c.verdict != "DISAGREE", c.as_dict()


def test_an_overload_puts_the_player_in_its_safe_state_and_monitor_shows_it(
    any_board, gait, tmp_path
):
    """A servo pushed harder than it can hold reports OVERLOAD, its alarm shutdown cuts its
    torque; the firmware's next telemetry read of it sees the error bit (in its default
    Servo Error Mask), stops the gait, enters SAFE and switches every servo's torque off
    (Safe Action TORQUE_OFF)."""
    robot = any_board
    path = tmp_path / "walk.gait"
    write_gait(path, gait.gait_table())
    port = robot.info.pc_link
    cli("stop", "--port", port, "--clear")
    cli("upload", path, "--port", port, "--new-servos")
    assert json.loads(cli("play", "--port", port, "--loop", "--json"))["state"] == "PLAYING"
    time.sleep(0.3)
    victim = robot.robot.servo_ids[1]
    robot.push(victim, OVERLOAD_TORQUE_NM)

    end = time.monotonic() + ALARM_TIMEOUT_S
    while True:
        out = cli("monitor", "--port", port, "--json", "--duration", "0")
        sample = json.loads(out.splitlines()[-1])
        if sample["controller"]["state"] == "SAFE" or time.monotonic() > end:
            break
        time.sleep(0.1)
    controller = sample["controller"]
    assert controller["state"] == "SAFE", controller
    assert "SERVO_ERROR" in controller["error_flags"]
    servos = {s["id"]: s for s in sample["servos"]}
    assert "OVERLOAD" in servos[victim]["error"]
    assert servos[victim]["error_count"] >= 1
    assert all("OVERLOAD" not in s["error"] for i, s in servos.items() if i != victim)

    # The safe action reached the servos: torque off everywhere, nothing moves any more.
    with robot.lock:
        torque = [robot.servo(i).regs.get("Torque Enable") for i in robot.robot.servo_ids]
    assert torque == [0] * len(torque)
    first = robot.positions()
    time.sleep(0.3)
    assert robot.positions() == first

    # PLAY is refused while the fault stands; the text monitor says why.
    refused = CliRunner().invoke(main, ["play", "--port", port])
    # the safe state is a runtime state, not bad input: exit 1 (as from every command)
    assert refused.exit_code == 1 and "safe state" in refused.output
    text = cli("monitor", "--port", port, "--duration", "0")
    assert "SAFE" in text and "overload" in text.lower()
