"""The kinematic world's servos under the body's load (issue #31): the physics world's
actuators turning the quasi-static body's joints, on the real emulated bus, beside real
MuJoCo. Their joints lag and smooth the table's one-tick steps as MuJoCo's do, so at a
large phase step the kinematic world goes as far as MuJoCo, not a third less."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snakebot.facts import devices
from snakebot.link.transport import DxlClient
from snakebot.model.gait import serpenoid
from snakebot.model.robots import load_robot
from snakebot.sim.physics.joints import LoadedWorld
from snakebot.sim.physics.select import make_world
from snakebot.sim.world import World
from snakebot.workflows.friction import repeated
from snakebot.workflows.predict import predict_gait, sim_url

pytest.importorskip("mujoco")

SNAKE5 = load_robot("snake5")
AX12 = devices.ax12()
GOAL_POSITION, PRESENT_LOAD, TORQUE_ENABLE = (
    AX12.register(name).address for name in ("Goal Position", "Present Load", "Torque Enable")
)


def last_pass(pose: np.ndarray, passes: int = 3) -> float:
    per = (len(pose) - 1) // passes
    return math.hypot(*(pose[-1, :2] - pose[-1 - per, :2]))


@pytest.fixture(scope="module")
def delta_150():
    """A = 20 deg, delta = 150 deg, omega = 180 deg/s played three times in both worlds:
    the gait whose forward motion is the smallest difference of sideways ones."""
    gait = serpenoid(SNAKE5, math.radians(20), math.pi, math.radians(150), cycles=1, rate_hz=50)
    played = repeated(gait.gait_table(), 3)
    return predict_gait(played, SNAKE5), predict_gait(played, SNAKE5, world="mujoco")


def test_modelled_servos_get_the_loaded_world_and_ideal_ones_the_plain_one():
    for ideal, kind in ((False, LoadedWorld), (True, World)):
        client = DxlClient(sim_url(SNAKE5, ideal), echo=False)
        try:
            world = make_world("kinematic", client.port.bus, SNAKE5, period=0.01)
            assert type(world) is kind
            world.stop()
        finally:
            client.close()


def test_at_delta_150_deg_the_joints_move_as_mujocos_and_the_body_goes_as_far(delta_150):
    kinematic, mujoco = delta_150
    # the joints lag their goals under the load, as MuJoCo's do (3.1 deg; the servos' own
    # model kept within 0.84 deg); and they follow MuJoCo's joints (0.53 deg; 2.3 before)
    n = len(kinematic.emulated.t)
    last = slice(n - 1 - (n - 1) // 3, n)
    lag = np.degrees(np.abs(kinematic.joint_error[last])).max()
    assert lag > 1.5
    apart = np.degrees(np.abs(kinematic.emulated.phi[last] - mujoco.emulated.phi[last]))
    assert apart.max() < 1.0
    # so the body goes as far as MuJoCo's (the table's ticks played exactly: 0.066 m
    # against MuJoCo's 0.101 m)
    assert last_pass(kinematic.emulated.pose) == pytest.approx(
        last_pass(mujoco.emulated.pose), rel=0.05
    )


def test_the_load_is_the_bodys_and_the_servos_report_it():
    client = DxlClient(sim_url(SNAKE5, False), echo=False)
    try:
        bus = client.port.bus
        world = LoadedWorld(bus, SNAKE5)
        bus.run_until(bus.now + 0.2)
        assert np.all(world.load == 0.0)  # at rest: no friction to carry
        assert client.read_u16(SNAKE5.servo_ids[1], PRESENT_LOAD) & 1023 == 0
        # one joint turns: the links on both sides drag their wheels sideways
        sid, joint = SNAKE5.servo_ids[1], SNAKE5.joints[1]
        client.write_u16(sid, GOAL_POSITION, joint.angle_to_tick(math.radians(45)))
        bus.run_until(bus.now + 0.1)
        load = client.read_u16(sid, PRESENT_LOAD)
        assert world.load[1] > 0.05  # N m, against the motion (CCW)
        # Present Load: the motor's torque (the drive less the back-EMF), CCW
        assert 40 < load & 1023 < 300 and not load & 1024
        world.stop()
        assert not any(s.world_driven for s in bus.servos)  # their own motion again
    finally:
        client.close()


def test_a_tenth_of_the_step_moves_the_body_little():
    def moved(step: float) -> np.ndarray:
        client = DxlClient(sim_url(SNAKE5, False), echo=False)
        try:
            bus = client.port.bus
            world = LoadedWorld(bus, SNAKE5, step=step)
            # every joint to 40 deg at once: the snake curls up, dragging its wheels
            for sid, joint in zip(SNAKE5.servo_ids, SNAKE5.joints, strict=True):
                client.write_u16(sid, GOAL_POSITION, joint.angle_to_tick(math.radians(40)))
            bus.run_until(bus.now + 1.0)
            world.stop()
            return world.record().q[-1]
        finally:
            client.close()

    coarse, fine = moved(0.001), moved(0.0001)
    assert np.degrees(coarse[3:]) == pytest.approx([40, 40, 40, 40], abs=1.5)
    distance = math.hypot(*fine[:2])
    assert distance > 0.005 and abs(fine[2]) > 0.1  # it moves and turns
    assert math.hypot(*(coarse[:2] - fine[:2])) < 0.02 * distance
    assert coarse[2] == pytest.approx(fine[2], rel=0.02)


def test_a_joint_pushed_to_its_stop_leaves_the_rest_still_once_torque_is_off():
    """The stop, not the body, takes a push that holds a joint there; and joints with no
    drive come to rest rather than chatter and creep (the firmware's safe state)."""
    client = DxlClient(sim_url(SNAKE5, False), echo=False)
    try:
        bus = client.port.bus
        world = LoadedWorld(bus, SNAKE5)
        victim = SNAKE5.servo_ids[1]
        bus.servo(victim).set_external_torque(bus.now, 5.0)  # past stall: to its stop
        bus.run_until(bus.now + 0.3)
        for sid in SNAKE5.servo_ids:
            client.write_u8(sid, TORQUE_ENABLE, 0)
        bus.run_until(bus.now + 0.2)
        still = bus.positions(SNAKE5.servo_ids)
        joint = SNAKE5.joints[1]
        assert world.record().q[-1, 4] in (joint.min_rad, joint.max_rad)  # at its stop
        bus.run_until(bus.now + 1.0)
        assert bus.positions(SNAKE5.servo_ids) == still
        world.stop()
    finally:
        client.close()
