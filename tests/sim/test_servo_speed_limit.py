"""How Moving Speed acts on a joint in the physics world, chosen in the robot file
(``[servo] speed_limit``, docs/models.md "The servo's speed limit"): "drive" caps the
motor's drive at the duty that turns the unloaded motor at that speed, so a slow speed
also caps the torque that holds a joint; "profile" moves the servo's target to the goal
at that speed and holds with the full drive. Real MuJoCo, the servos on an emulated bus."""

from __future__ import annotations

import dataclasses
import math
from importlib import resources

import pytest

from snakebot.facts import devices
from snakebot.link.transport import DxlClient
from snakebot.model.robots import TICKS_PER_RAD, RobotError, load_robot, parse_robot
from snakebot.workflows.predict import sim_url

pytest.importorskip("mujoco")

from snakebot.sim.physics import PhysicsWorld  # noqa: E402

SNAKE5 = load_robot("snake5")
AX12 = devices.ax12()
GOAL_POSITION = AX12.register("Goal Position").address
SPEED = AX12.register("Moving Speed")
SLOW = 100  # raw Moving Speed: 11 rpm, a fifth of the no-load speed
PUSH_NM = 0.6  # twice what the drive capped at that speed gives, 40 % of stall


def world_with(speed_limit: str):
    robot = dataclasses.replace(SNAKE5, speed_limit=speed_limit)
    client = DxlClient(sim_url(robot, False), echo=False)
    bus = client.port.bus
    sid = robot.servo_ids[1]
    client.write_u16(sid, SPEED.address, SLOW)
    world = PhysicsWorld(bus, robot)
    return client, bus, world, sid


def moved_in_half_a_second(speed_limit: str) -> tuple[float, float]:
    """(ticks moved, ticks Moving Speed allows) in 0.5 s toward a goal 200 ticks away."""
    client, bus, world, sid = world_with(speed_limit)
    start = bus.servo(sid).pos
    client.write_u16(sid, GOAL_POSITION, round(start) + 200)
    bus.run_until(bus.now + 0.5)
    moved = bus.servo(sid).pos - start
    world.stop()
    client.close()
    rad_s = SPEED.to_units(SLOW) * 2 * math.pi / 60  # the register is in rpm
    return moved, rad_s * 0.5 * TICKS_PER_RAD


def test_with_profile_a_joint_moves_at_its_moving_speed():
    moved, allowed = moved_in_half_a_second("profile")
    assert moved == pytest.approx(allowed, rel=0.15)  # less the lag the load takes


def test_with_drive_a_joint_under_load_moves_slower_than_its_moving_speed():
    # the capped duty turns the unloaded motor at that speed; the chain's load slows it
    moved, allowed = moved_in_half_a_second("drive")
    assert 0.2 * allowed < moved < 0.9 * allowed


def held_against_a_push(speed_limit: str) -> float:
    """How far (degrees) a joint holding still at a slow Moving Speed gives way in 1 s
    under a steady torque of PUSH_NM on it."""
    client, bus, world, sid = world_with(speed_limit)
    bus.run_until(bus.now + 0.2)
    start = bus.servo(sid).pos
    client.write_u16(sid, GOAL_POSITION, round(start))
    bus.run_until(bus.now + 0.2)
    bus.servo(sid).set_external_torque(bus.now, PUSH_NM)  # on the horn
    bus.run_until(bus.now + 1.0)
    gave = math.degrees(abs(bus.servo(sid).pos - start) / TICKS_PER_RAD)
    world.stop()
    client.close()
    return gave


def test_with_drive_a_slow_speed_also_caps_the_holding_torque():
    assert held_against_a_push("drive") > 30.0


def test_with_profile_the_full_drive_holds_the_joint():
    assert held_against_a_push("profile") < 8.0


def test_the_robot_file_chooses_and_a_wrong_value_is_refused():
    text = resources.files("snakebot.model.robots").joinpath("snake5.toml").read_text()
    chosen = text.replace('model = "AX-12A"', 'model = "AX-12A"\nspeed_limit = "profile"')
    assert parse_robot(chosen, "p.toml").speed_limit == "profile"
    assert parse_robot(text, "d.toml").speed_limit == "drive"
    wrong = text.replace('model = "AX-12A"', 'model = "AX-12A"\nspeed_limit = "torque"')
    with pytest.raises(
        RobotError, match=r"servo.speed_limit' must be 'drive' or 'profile', not 'torque'"
    ):
        parse_robot(wrong, "w.toml")
