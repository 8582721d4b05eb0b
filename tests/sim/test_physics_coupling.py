"""The physics world's per-tick coupling in C (sim_world.c) against the Python models it
follows, to the last bit: the actuator's drive law (``Actuator.drive``), the motor's
electrical power (``MotorSpec.electrical_power_w``), and, in a running world, the drive
MuJoCo is given for each joint from its servo's registers."""

from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from snakebot.core import ffi, lib
from snakebot.formats.protocol import sync_write
from snakebot.model.robots import TICKS_PER_RAD, load_robot
from snakebot.sim.options import SimOptions
from snakebot.sim.physics.actuator import Actuator
from snakebot.sim.physics.coupling import actuator_struct
from snakebot.sim.servo import motor

pytest.importorskip("mujoco")

from snakebot.sim.physics import PhysicsWorld  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
MODELS = ("AX-12A", "AX-12W")
ACTUATORS = {m: Actuator.for_model(m) for m in MODELS}
STRUCTS = {m: actuator_struct(a) for m, a in ACTUATORS.items()}


def c_drive(model: str, controller: tuple[float, ...], pos: float) -> tuple:
    out = ffi.new("double[4]")
    cut = lib.sim_actuator_drive(STRUCTS[model], list(controller), pos, out)
    return (*out, bool(cut))


controllers = st.tuples(
    st.integers(0, 1023).map(float),  # goal
    st.one_of(st.just(math.inf), st.floats(1.0, 2e4)),  # speed setting, ticks/s
    st.sampled_from([0.0, 1.0]),  # torque on
    st.integers(0, 1023).map(float),  # Torque Limit
    st.integers(0, 255).map(float),  # CW margin
    st.integers(0, 255).map(float),  # CCW margin
    st.integers(1, 254).map(float),  # CW slope
    st.integers(1, 254).map(float),  # CCW slope
    st.integers(0, 1023).map(float),  # Punch
    st.one_of(st.just(0.0), st.floats(0.0, 16.0)),  # supply volts
    st.sampled_from([0.0, 1.0]),  # wheel mode
    st.integers(0, 2047).map(float),  # raw Moving Speed
)


@settings(max_examples=400, deadline=None)
@given(model=st.sampled_from(MODELS), controller=controllers, pos=st.floats(-200.0, 1300.0))
def test_the_c_drive_is_the_actuator_models_to_the_bit(model, controller, pos):
    assert c_drive(model, controller, pos) == ACTUATORS[model].drive(controller, pos)


@settings(max_examples=200, deadline=None)
@given(
    model=st.sampled_from(MODELS),
    torque=st.floats(-3.0, 3.0),
    speed=st.floats(-50.0, 50.0),
)
def test_the_c_power_is_the_motor_models_to_the_bit(model, torque, speed):
    expected = motor.spec_for(model).electrical_power_w(torque, speed)
    assert lib.sim_actuator_power(STRUCTS[model], torque, speed) == expected


def python_drives(world: PhysicsWorld) -> np.ndarray:
    """Each joint's (bias constant, bias slope, force range) as the Python models give
    them from its servo's registers and the joint's angle now."""
    rows = []
    stall_per_volt = world.actuator.stall_nm / world.actuator.nominal_v
    angles = world.record().phi[-1]  # sampled at the last tick, where the drives were set
    for joint, sid, angle in zip(world.robot.joints, world.robot.servo_ids, angles, strict=True):
        sign, zero = float(joint.sign), float(joint.zero_tick)
        pos = zero + sign * float(angle) * TICKS_PER_RAD
        controller = world.bus.servo(sid).controller()
        gain, target, offset, cap, _ = world.actuator.drive(controller, pos)
        stall = stall_per_volt * controller[9] if controller[9] > 0.0 else 0.0
        constant = sign * stall * (gain * (target - zero) + offset)
        rows.append((constant, -stall * gain * TICKS_PER_RAD, -stall * cap, stall * cap))
    return np.array(rows)


def test_a_running_world_drives_each_joint_as_the_python_models_say():
    robot = load_robot("snake5")
    bus = SimOptions(robot="snake5").build_bus()
    ids = robot.servo_ids
    bus.servo(ids[0]).set_register("Torque Limit", 200)  # cut: the duty is capped
    bus.servo(ids[1]).set_register("CCW Angle Limit", 0)  # wheel mode
    bus.servo(ids[1]).set_register("Moving Speed", 1024 | 300)
    bus.servo(ids[2]).set_register("Punch", 300)
    bus.servo(ids[2]).set_register("CW Compliance Slope", 128)
    bus.servo(ids[3]).supply_v = 9.0
    world = PhysicsWorld(bus, robot)
    law_in_force = np.zeros(robot.n_joints, dtype=bool)
    for k in range(60):
        t = 0.02 * k
        phi = 1.0 * np.sin(2 * math.pi * t + np.arange(robot.n_joints) * math.pi / 2)
        goals = {
            sid: int(g).to_bytes(2, "little")
            for sid, g in zip(ids, robot.angles_to_ticks(phi), strict=True)
            if sid != ids[1]
        }
        bus.master_write(sync_write(30, 2, goals))
        if k == 30:
            bus.servo(ids[3]).set_register("Torque Enable", 0)
        bus.run_until(t + 0.015)  # past a tick, before the next
        m = world.model
        given_now = np.column_stack((m.actuator_biasprm[:, :2], m.actuator_forcerange))
        assert np.array_equal(given_now, python_drives(world)), k
        law_in_force |= given_now[:, 1] != 0.0
    # the position law drove the joint servos; the wheel-mode one only ever its Moving Speed
    assert law_in_force.tolist() == [True, False, True, True]


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_the_c_coupling_compiles_clean_with_warnings_as_errors():
    csrc = ROOT / "host" / "snakebot" / "sim" / "csrc"
    result = subprocess.run(
        ["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-fsyntax-only"]
        + ["-I", str(ROOT / "firmware" / "core"), "-I", str(csrc), str(csrc / "sim_world.c")],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
