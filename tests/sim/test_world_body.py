"""The world: joint angles from the virtual servos' present positions, the body moved
through the C kinematic core on the bus's clock, batching, and singular crossings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snakebot.formats.protocol import sync_write
from snakebot.model.robots import TICKS_PER_RAD, load_robot
from snakebot.sim.bus.bus import Bus
from snakebot.sim.options import SimOptions
from snakebot.sim.servo.fast import VirtualServo
from snakebot.sim.world import World, WorldError

GOAL = 30  # Goal Position, then Moving Speed


def drive(bus: Bus, goals: dict[int, int], speed: int = 0) -> None:
    """The master sends one SYNC_WRITE of goal and speed to the servos, now."""
    block = {sid: g.to_bytes(2, "little") + speed.to_bytes(2, "little") for sid, g in goals.items()}
    bus.master_write(sync_write(GOAL, 4, block))


def play_ticks(bus: Bus, ids: tuple[int, ...], rows: np.ndarray, period: float) -> None:
    """One SYNC_WRITE per row, every ``period`` seconds of bus time, from now."""
    start = bus.now
    for k, row in enumerate(rows):
        bus.run_until(start + k * period)
        drive(bus, {sid: int(t) for sid, t in zip(ids, row, strict=True)})
    bus.run_until(start + len(rows) * period)


MIRRORED = """
name = "mirrored"
kind = "snake"
[geometry]
links = 3
half_link = 0.1
[friction]
c_n = 1.0
c_t = 0.02
[servo]
model = "AX-12A"
[[joints]]
name = "a"
servo_id = 7
zero_tick = 600
sign = -1
min_deg = -90.0
max_deg = 90.0
[[joints]]
name = "b"
servo_id = 3
zero_tick = 450
sign = 1
min_deg = -90.0
max_deg = 90.0
"""


@pytest.fixture()
def mirrored(tmp_path):
    path = tmp_path / "mirrored.toml"
    path.write_text(MIRRORED)
    return load_robot(str(path))


def test_joint_angles_come_from_present_positions_through_zero_and_sign(mirrored):
    bus = SimOptions(robot=mirrored.source, ideal=True).build_bus()
    world = World(bus, mirrored, period=0.01)
    drive(bus, {7: 700, 3: 400})
    bus.run_until(0.05)
    rec = world.record()
    # at t = 0 the servos sit at their zero ticks: both angles 0
    assert rec.phi[0] == pytest.approx([0.0, 0.0], abs=1e-12)
    # afterwards servo 7 (sign -1, zero 600) at 700 and servo 3 (zero 450) at 400
    expected = [(700 - 600) / (-1 * TICKS_PER_RAD), (400 - 450) / TICKS_PER_RAD]
    assert rec.phi[-1] == pytest.approx(expected, abs=1e-12)
    assert expected[0] < 0 and expected[1] < 0
    assert len(rec.t) == 6 and rec.t == pytest.approx(np.arange(6) * 0.01)


def test_body_rests_while_the_servos_rest():
    robot = load_robot("snake5")
    bus = SimOptions(robot="snake5").build_bus()
    world = World(bus, robot, period=0.01, pose=(1.0, -2.0, 0.5))
    bus.run_until(0.5)
    rec = world.record()
    assert len(rec.t) == 51
    assert np.all(rec.pose == np.array([1.0, -2.0, 0.5]))
    assert rec.slip_max() == 0.0
    assert not rec.regularised.any()


def test_servo_motion_moves_the_body_and_slips_a_five_link_snake():
    robot = load_robot("snake5")
    bus = SimOptions(robot="snake5").build_bus()  # modelled AX-12As
    world = World(bus, robot, period=0.01)
    t = np.arange(100) * 0.02
    phi = 0.5 * np.sin(2 * math.pi * t[:, None] + np.arange(4) * math.pi / 2)
    play_ticks(bus, robot.servo_ids, robot.angles_to_ticks(phi), 0.02)
    rec = world.record()
    assert np.isfinite(rec.pose).all()
    assert np.hypot(*rec.pose[-1, :2]) > 0.05  # the snake went somewhere
    # five wheels, four joints: the constraints conflict, so the wheels slip
    assert rec.slip_max() > 1e-4
    assert rec.slip_distance().shape == (5,)
    assert (rec.slip_distance() > 0).all()


def run_serpenoid(batch: int, ideal: bool):
    robot = load_robot("snake5")
    bus = SimOptions(robot="snake5", ideal=ideal).build_bus()
    world = World(bus, robot, period=0.01, batch=batch)
    t = np.arange(60) * 0.02
    phi = 0.4 * np.sin(3 * t[:, None] + np.arange(4) * 1.2)
    play_ticks(bus, robot.servo_ids, robot.angles_to_ticks(phi), 0.02)
    samples_before = world.samples
    mid_pose = world.pose  # forces a flush part way through for small batches
    assert world.samples == samples_before
    bus.run_until(bus.now + 0.305)  # settle; the last sample at 1.5 s
    return world.record(), mid_pose


@pytest.mark.parametrize("ideal", [False, True])
def test_batch_size_does_not_change_the_result(ideal):
    one, mid1 = run_serpenoid(1, ideal)
    seven, mid7 = run_serpenoid(7, ideal)
    whole, mid_whole = run_serpenoid(10_000, ideal)
    assert len(one.t) == len(seven.t) == len(whole.t) == 151
    for rec in (one, seven):
        assert np.abs(rec.pose - whole.pose).max() < 1e-9
        assert np.abs(rec.phi - whole.phi).max() == 0.0
        assert np.abs(rec.slip - whole.slip).max() < 1e-9
    assert mid1 == pytest.approx(mid_whole, abs=1e-9)
    assert mid7 == pytest.approx(mid_whole, abs=1e-9)
    assert np.abs(whole.pose[-1, :2]).max() > 0.01


def test_stop_ends_sampling_and_keeps_the_record():
    robot = load_robot("snake3")
    bus = SimOptions(robot="snake3").build_bus()
    world = World(bus, robot, period=0.01)
    bus.run_until(0.1)
    world.stop()
    bus.run_until(1.0)
    assert not world.running
    assert len(world.record().t) == 11


def test_inadmissible_crossing_of_the_three_link_singular_line_stays_finite():
    """phi1 sweeps through phi2 with phi2 held: a crossing of phi1 = phi2 in a direction
    ideal wheels cannot follow. The world regularises those intervals only, stays
    finite, and reports the slip the wheels took there."""
    robot = load_robot("snake3")
    assert robot.c_t == 0.0
    bus = SimOptions(robot="snake3", ideal=True).build_bus()
    ids = robot.servo_ids
    drive(bus, dict(zip(ids, robot.angles_to_ticks(np.array([0.3, 0.1])).tolist(), strict=True)))
    bus.run_until(0.005)
    world = World(bus, robot, period=0.01)
    p1 = np.linspace(0.3, -0.1, 41)
    rows = robot.angles_to_ticks(np.column_stack([p1, np.full_like(p1, 0.1)]))
    play_ticks(bus, ids, rows, 0.01)
    rec = world.record()
    assert np.isfinite(rec.pose).all() and np.isfinite(rec.slip).all()
    crossing = np.flatnonzero(rec.regularised)
    assert 1 <= len(crossing) <= 4
    # the regularised intervals are the ones that touch phi1 = phi2
    gap = rec.phi[:, 0] - rec.phi[:, 1]
    for k in crossing:
        assert min(abs(gap[k - 1]), abs(gap[k])) < 0.02
    # ideal wheels do not slip elsewhere; at the crossing they must
    calm = np.ones(len(rec.t), dtype=bool)
    calm[crossing] = False
    assert np.abs(rec.slip[calm]).max() < 1e-9
    assert np.abs(rec.slip[crossing]).max() > 1e-3
    assert rec.fallback_c_t == pytest.approx(1e-3)


def test_ideal_wheels_without_a_fallback_report_the_singular_crossing():
    robot = load_robot("snake3")
    bus = SimOptions(robot="snake3", ideal=True).build_bus()
    ids = robot.servo_ids
    # from the straight (singular) pose, start off along (1, 1): not admissible
    world = World(bus, robot, period=0.01, regularise=False)
    assert world.fallback_c_t is None
    play_ticks(bus, ids, np.array([[560, 560], [600, 600]]), 0.01)
    with pytest.raises(WorldError, match="cannot follow the servos"):
        world.record()


def test_a_robot_whose_servos_are_not_on_the_bus_is_refused():
    robot = load_robot("snake5")
    bus = Bus([VirtualServo(1), VirtualServo(2)])
    with pytest.raises(WorldError, match="no servo with ID 10, 11, 15, 16"):
        World(bus, robot)
