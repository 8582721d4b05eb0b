"""Live steering on the real firmware, on both boards (the CM-530's image on the emulated
STM32F103RE, the qemu board's build in QEMU): a large step in Serp Phi0 written while the
serpenoid runs reaches the emulated servos as a slew, every goal they receive within what
the servo covers at its top speed in the time since the previous one (the bound the
firmware derives from ax12_table.h, checked against the description in
tests/model/test_slew.py), and the wave ends up offset by the new phi0."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from firmware_support import BOARDS, board_value, build_firmware, emulated_robot

from snakebot.core import lib
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.playback import SerpenoidSettings, roster_from_robot, serpenoid
from snakebot.sim.serve import EmulatedRobot

pytestmark = [pytest.mark.qemu, pytest.mark.slow, pytest.mark.serial]

PHI0_STEP = math.radians(50)  # about eight ticks' worth of the servo's top speed
OMEGA = math.pi
PERIOD_S = 2 * math.pi / OMEGA
WINDOW_S = 1.5 * PERIOD_S  # the wave's middle is half-way between its extremes over this


def _record_goals(robot: EmulatedRobot) -> dict[int, list[tuple[float, int]]]:
    """From now on, each servo's received Goal Positions with their bus times."""
    received: dict[int, list[tuple[float, int]]] = {}
    with robot.lock:
        robot.bus.tap()  # goals through the Python handlers wrapped here, not whole to C
        for joint in robot.robot.joints:
            servo = robot.servo(joint.servo_id)
            log = received.setdefault(joint.servo_id, [])
            deliver = servo.sync_write_block

            def hear(address, data, t, servo=servo, log=log, deliver=deliver):
                deliver(address, data, t)
                log.append((t, servo.regs.get("Goal Position")))

            servo.sync_write_block = hear
    return received


def _bus_wait(robot: EmulatedRobot, seconds: float) -> None:
    """Wait until the bus clock has run ``seconds``: the emulated CM-530 slows its clock
    when the host keeps it waiting, so wall time may show the firmware less of the wave
    (bounded: ten times as long, and 10 s more)."""
    with robot.lock:
        end = robot.bus.now + seconds
    deadline = time.monotonic() + 10 * seconds + 10.0
    while True:
        with robot.lock:
            left = end - robot.bus.now
        if left <= 0:
            return
        assert time.monotonic() < deadline, f"the bus clock stood still ({left:.2f} s left)"
        time.sleep(min(left, 0.1))


@pytest.mark.parametrize("board", BOARDS)
def test_a_large_phi0_step_reaches_the_servos_slewed(board: str):
    build_firmware()
    tick_ms = board_value(board, "BOARD_CONTROL_TICK_MS")  # a goal may come one tick late
    with emulated_robot("snake5", board) as robot:
        ctl = ControllerClient.open(robot.info.pc_link)
        try:
            wave = SerpenoidSettings(amplitude=math.radians(20), omega=OMEGA, delta=1.5)
            serpenoid(ctl, wave, roster=roster_from_robot(robot.robot))
            _bus_wait(robot, 1.0)
            received = _record_goals(robot)
            _bus_wait(robot, WINDOW_S + 0.3)
            with robot.lock:
                before = {sid: len(log) for sid, log in received.items()}
            phi0 = ctl.table.register("Serp Phi0").from_units(PHI0_STEP, "rad")
            ctl.write({"Serp Phi0": phi0})
            _bus_wait(robot, WINDOW_S + 1.0)
            ctl.command("STOP")
        finally:
            ctl.close()
        with robot.lock:
            logs = {sid: list(log) for sid, log in received.items()}

    for joint in robot.robot.joints:
        t, goals = (np.array(v) for v in zip(*logs[joint.servo_id], strict=True))
        assert len(goals) > 200  # goals kept coming at the control tick
        dt_ms = np.diff(t) * 1000
        bounds = [lib.play_slew_step_bound(int(math.ceil(d)) + tick_ms) for d in dt_ms]
        steps = np.abs(np.diff(goals))
        worst = np.argmax(steps - bounds)
        assert np.all(steps <= bounds), (joint.name, steps[worst], bounds[worst], dt_ms[worst])
        # the wave is offset by the new phi0: its middle moved by that much
        split = before[joint.servo_id]
        after = t[-1] - t <= WINDOW_S
        earlier = (t[split - 1] - t <= WINDOW_S) & (np.arange(len(t)) < split)
        shift = _middle(joint, goals[after]) - _middle(joint, goals[earlier])
        assert shift == pytest.approx(PHI0_STEP, abs=math.radians(3)), joint.name


def _middle(joint, goals: np.ndarray) -> float:
    """The joint angle half-way between the wave's extremes."""
    return (joint.tick_to_angle(goals.max()) + joint.tick_to_angle(goals.min())) / 2
