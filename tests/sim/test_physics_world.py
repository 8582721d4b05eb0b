"""The MuJoCo world: real MuJoCo, virtual AX-12s on an emulated bus, the host as master.

The checks of issue #12: no input, no motion; very grippy wheels reproduce the kinematic
prediction; slippery ones slip; the motors' energy is positive; runs repeat exactly; the
servos report the physics' load and overload; bad robot files are refused by key.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from physics_support import snake5_serpenoid

from snakebot.formats.protocol import ErrorFlags
from snakebot.link.transport import DxlClient
from snakebot.model.robots import RobotError, load_robot, parse_robot
from snakebot.sim.physics import PhysicsError, PhysicsWorld
from snakebot.sim.physics.mjcf import build_mjcf
from snakebot.workflows.predict import predict_gait, predict_table, sim_url

pytest.importorskip("mujoco")

SNAKE5 = load_robot("snake5")
GOAL_POSITION = 30
TORQUE_LIMIT = 34
PRESENT_LOAD = 40


@pytest.fixture(scope="module")
def s5_table():
    return snake5_serpenoid()


@pytest.fixture(scope="module")
def kinematic_free_wheels(s5_table):
    """The kinematic prediction for free-rolling wheels (no rolling resistance or axle
    friction), the limit the grippy run approaches: its lateral friction is so high
    that rolling resistance is negligible beside it."""
    intervals = s5_table.frame_count if s5_table.loop else s5_table.frame_count - 1
    free = dataclasses.replace(SNAKE5.friction, rolling=0.0, axle_nm=0.0)
    traj, _ = predict_table(dataclasses.replace(SNAKE5, friction=free), s5_table, intervals + 1)
    return traj.q[-1, :2] - traj.q[0, :2]


def run(table, mu):
    return predict_gait(table, "snake5", world="mujoco", mu=mu)


@pytest.fixture(scope="module")
def grippy(s5_table):
    return run(s5_table, 20.0)


@pytest.fixture(scope="module")
def slippery(s5_table):
    return run(s5_table, 0.05)


def distance(result):
    d = result.emulated.displacement()
    return math.hypot(d["dx"], d["dy"])


@pytest.fixture()
def bus_client():
    client = DxlClient(sim_url(SNAKE5, False), echo=False)
    yield client, client.port.bus
    client.close()


@pytest.mark.parametrize("name", ["snake5", "snake3", "trident"])
def test_each_wheel_carries_the_load_the_robot_file_gives_it(name):
    """The quasi-static model weighs each wheel's friction by its load
    (``Robot.wheel_loads_n``); MuJoCo's contacts must carry the same loads, bent or
    straight. On one z for a whole snake the contact solver spread the weight by its
    regularisation instead: snake5's end wheels 0.69 N, its middle one 1.02 N."""
    import mujoco

    robot = load_robot(name)
    xml, names = build_mjcf(robot)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    wheels = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, w) for w in names.wheels]
    for shape in (0.0, 0.6):
        mujoco.mj_resetData(model, data)
        for k, joint in enumerate(names.joints):
            data.joint(joint).qpos = shape * (-1) ** k
        for _ in range(1000):
            mujoco.mj_step(model, data)
        loads = np.zeros(len(wheels))
        force = np.zeros(6)
        for i in range(data.ncon):
            contact = data.contact[i]
            body = model.geom_bodyid[contact.geom2 if contact.geom1 == 0 else contact.geom1]
            mujoco.mj_contactForce(model, data, i, force)
            loads[wheels.index(body)] += force[0]
        np.testing.assert_allclose(loads, robot.wheel_loads_n(), rtol=0.005)


def test_zero_input_gives_no_motion_in_ten_seconds(bus_client):
    client, bus = bus_client
    # the servos hold where they are, torque on
    for sid in SNAKE5.servo_ids:
        client.write_u16(sid, GOAL_POSITION, bus.servo(sid).present_position)
    world = PhysicsWorld(bus, SNAKE5)
    bus.run_until(bus.now + 10.0)
    world.stop()
    rec = world.record()
    assert rec.t[-1] == pytest.approx(10.0)
    moved = np.hypot(*(rec.pose[:, :2] - rec.pose[0, :2]).T) * SNAKE5.physics.unit_m
    assert moved.max() < 1e-4
    assert np.abs(rec.pose[:, 2] - rec.pose[0, 2]).max() < 1e-3


def test_very_high_lateral_friction_converges_to_the_kinematic_prediction(
    grippy, kinematic_free_wheels
):
    # measured 5.3 % short (3.6 % while MuJoCo's contacts spread the weight unevenly):
    # at mu = 20 no wheel's friction saturates, so the five wheels, more than the body
    # has freedoms, share their slip as the contact solver's softness does (least
    # squares), where the quasi-static model has Coulomb's (the fewest wheels slide)
    expected = float(np.hypot(*kinematic_free_wheels))
    assert distance(grippy) == pytest.approx(expected, rel=0.06)
    # and the direction of travel agrees too
    d = grippy.emulated.displacement()
    heading = math.atan2(d["dy"], d["dx"])
    assert heading == pytest.approx(math.atan2(*kinematic_free_wheels[::-1]), abs=0.05)


def test_low_lateral_friction_makes_the_wheels_slip(grippy, slippery):
    slid = slippery.emulated.slip_distance().sum()
    held = grippy.emulated.slip_distance().sum()
    assert slid > 3 * held
    assert slid > 0.01  # metres over one cycle: measurable
    assert distance(slippery) < 0.8 * distance(grippy)


def test_work_and_electrical_energy_are_consistent_and_the_report_is_finite(grippy, slippery):
    # what the motors put in, all told, is what friction and the gears' braking take out
    # (the body starts and ends nearly at rest): positive. One joint may be driven
    # backwards by the others and give some back, so only the total work must be positive.
    # The electrical energy is the work plus the windings' copper loss, never given back
    # to the supply: at least zero per joint and more than the work in all.
    for result in (grippy, slippery):
        rec = result.emulated
        assert rec.energy.sum() > 0.0
        assert (rec.electrical >= 0.0).all()
        assert rec.electrical.sum() > rec.energy.sum()
        summary = result.summary()
        assert summary["world"] == "mujoco"
        em = summary["emulated"]
        assert len(em["work_j"]) == len(em["electrical_j"]) == SNAKE5.n_joints
        assert len(em["wheel_slip_speed_max"]) == SNAKE5.n_wheels
        assert 0.0 < max(em["peak_load"]) <= 1.0
        figures = em["work_j"] + em["electrical_j"] + em["slip_distance"]
        assert all(math.isfinite(v) for v in figures)


def test_a_run_is_deterministic(s5_table, grippy):
    again = run(s5_table, 20.0)
    assert np.array_equal(again.emulated.pose, grippy.emulated.pose)
    assert np.array_equal(again.emulated.energy, grippy.emulated.energy)


def test_present_load_and_overload_come_from_the_physics(bus_client):
    client, bus = bus_client
    sid = SNAKE5.servo_ids[0]
    joint = SNAKE5.joints[0]
    world = PhysicsWorld(bus, SNAKE5)
    client.write_u16(sid, TORQUE_LIMIT, 600)
    # a goal past the joint's mechanical limit: the link hits its stop and the servo
    # pushes against it with all that Torque Limit allows
    beyond = joint.angle_to_tick(joint.max_rad + math.radians(20))
    client.write_u16(sid, GOAL_POSITION, beyond)
    bus.run_until(bus.now + 0.6)  # at the stop (about 0.45 s at 600/1023 of full speed)
    load = client.read_u16(sid, PRESENT_LOAD)
    assert load & 1023 == pytest.approx(600, abs=30)  # all it may give, CCW
    assert not load & 1024
    bus.run_until(bus.now + 0.4)
    servo = bus.servo(sid)
    assert ErrorFlags.OVERLOAD in servo.errors
    assert servo.regs.get("Torque Limit") == 0  # the factory Shutdown cuts the torque
    bus.run_until(bus.now + 0.05)
    assert servo.load_fraction == 0.0  # a servo that drives nothing has no load
    world.stop()


def test_present_load_reads_the_motor_torque(bus_client):
    client, bus = bus_client
    sid = SNAKE5.servo_ids[1]
    world = PhysicsWorld(bus, SNAKE5)
    client.write_u16(sid, GOAL_POSITION, bus.servo(sid).present_position + 150)
    bus.run_until(bus.now + 0.05)
    load = client.read_u16(sid, PRESENT_LOAD)
    assert 100 < load & 1023  # accelerating the chain takes torque
    assert not load & 1024  # turning toward larger positions: CCW
    bus.run_until(bus.now + 2.0)
    assert client.read_u16(sid, PRESENT_LOAD) & 1023 < 30  # arrived: holds, little load
    world.stop()


def test_a_robot_without_physics_is_refused_naming_the_key():
    text = load_robot_text("snake3").split("\n[physics]")[0] + "\n"
    robot = parse_robot(text, "bare.toml")
    with pytest.raises(RobotError, match=r"bare.toml: key 'physics' is missing"):
        build_mjcf(robot)
    without_unit = text + "[physics]\nlink_mass_kg = 0.1\n"
    with pytest.raises(RobotError, match=r"key 'physics.unit_m' is missing"):
        parse_robot(without_unit, "nounit.toml")
    old = text + "[physics]\nunit_m = 0.1\nmu = 1\n"
    with pytest.raises(RobotError, match=r"key 'physics.mu'.*\[friction\] lateral"):
        parse_robot(old, "old.toml")
    negative = text.replace("lateral = 0.8", "lateral = -1")
    with pytest.raises(RobotError, match=r"key 'friction.lateral' must be > 0"):
        parse_robot(negative, "neg.toml")


def test_a_blow_up_stops_the_run_with_an_error(bus_client):
    _, bus = bus_client
    # a step far too coarse for the servos' stiffness and the contacts
    PhysicsWorld(bus, SNAKE5, period=0.5, control_period=0.5, timestep=0.5)
    for s in (bus.servo(i) for i in SNAKE5.servo_ids):
        s.set_register("Goal Position", 1000)
        s.set_register("Torque Enable", 1)
    with pytest.raises(PhysicsError, match="world time"):
        bus.run_until(bus.now + 20.0)


def load_robot_text(name):
    from importlib import resources

    return resources.files("snakebot.model.robots").joinpath(f"{name}.toml").read_text()


def no_load_speed(voltage):
    """Present Speed (ticks/s) of a servo swinging its link freely at ``voltage``."""
    with DxlClient(f"sim://?robot=snake5&world=mujoco&voltage={voltage}", echo=False) as c:
        bus = c.port.bus
        c.write_u16(16, GOAL_POSITION, 800)  # the tail joint: the lightest load
        bus.run_until(bus.now + 0.15)
        return bus.servo(16).vel


def test_the_motor_speed_scales_with_the_supply_voltage():
    fast, slow = no_load_speed(12.0), no_load_speed(8.0)
    assert slow / fast == pytest.approx(8.0 / 12.0, rel=0.1)
    # and it runs near the AX-12A's no-load 59 rpm, less what the link's load takes
    rpm = fast / (1023 / 300) / 6
    assert 40 < rpm <= 59
