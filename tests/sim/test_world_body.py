"""The world: joint angles from the virtual servos' shaft angles, the body moved
through the C kinematic core on the bus's clock, batching, and singular crossings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snakebot.formats.protocol import sync_write
from snakebot.model.robots import TICKS_PER_RAD, load_robot
from snakebot.sim.bus.bus import Bus
from snakebot.sim.options import SimOptions
from snakebot.sim.servo import motor
from snakebot.sim.servo.fast import VirtualServo
from snakebot.sim.servo.reference import ReferenceServo
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
lateral = 0.8
rolling = 0.02
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


@pytest.mark.parametrize("servo", [VirtualServo, ReferenceServo])
def test_joint_angles_are_the_shafts_continuous_angles_not_whole_ticks(mirrored, servo):
    """The body moves from where the shafts are, between ticks, while Present Position
    (what a READ returns) stays whole: a slow move (Moving Speed 10, about 23 ticks/s)
    crosses a tick every 4 to 5 samples, and the world sees it advance the same
    fraction of a tick at every sample; with the emulator's servo and the reference
    model alike."""
    bus = Bus([servo(7, position=600.0), servo(3, position=450.0)])  # modelled AX-12As
    world = World(bus, mirrored, period=0.01)
    drive(bus, {7: 700, 3: 450}, speed=10)
    bus.run_until(0.2)
    rec = world.record()
    ticks = 600 - rec.phi[:, 0] * TICKS_PER_RAD  # servo 7: zero tick 600, sign -1
    servo = bus.servo(7)
    assert ticks[-1] == pytest.approx(servo.pos, abs=1e-9)
    assert servo.present_position == round(servo.pos) != servo.pos
    speed = 10 * motor.SPEED_UNIT_RPM * motor.TICKS_PER_S_PER_RPM
    steps = np.diff(ticks[1:])  # whole intervals of the move (the write lands after 0)
    assert steps == pytest.approx(np.full(len(steps), speed * 0.01), abs=1e-9)
    assert 0.2 < steps[0] < 0.3  # a fraction of a tick: no whole-tick staircase
    assert np.abs(ticks[1:] - np.round(ticks[1:])).max() > 0.4


def test_body_rests_while_the_servos_rest():
    robot = load_robot("snake5")
    bus = SimOptions(robot="snake5").build_bus()
    world = World(bus, robot, period=0.01, pose=(1.0, -2.0, 0.5))
    bus.run_until(0.5)
    rec = world.record()
    assert len(rec.t) == 51
    assert np.all(rec.pose == np.array([1.0, -2.0, 0.5]))
    assert rec.slip_max() == 0.0


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
    # A batch only restarts the integrator's step-size control. The quasi-static body
    # velocity jumps where a wheel switches between rolling and sliding, and an adaptive
    # step's error estimate does not hold across a jump, so the batches agree to what
    # the jumps allow, not to the 1e-10 tolerance: measured 1.5e-7 with modelled servos
    # and 1.2e-6 with ideal ones (whose steps make more switches). The table moves the
    # body about 0.33: 5e-6 is 15 ppm of that.
    for rec in (one, seven):
        assert np.abs(rec.pose - whole.pose).max() < 5e-6
        assert np.abs(rec.phi - whole.phi).max() == 0.0
        assert np.abs(rec.slip - whole.slip).max() < 5e-5
    assert mid1 == pytest.approx(mid_whole, abs=5e-6)
    assert mid7 == pytest.approx(mid_whole, abs=5e-6)
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
    no-slip wheels cannot follow. The quasi-static world needs no special case. Three
    wheels for three body freedoms roll without sliding sideways while the lateral
    forces that rolling them needs stay within Coulomb friction; near the line those
    forces grow as 1 / (phi1 - phi2) and the wheels slide instead. With rolling
    resistance about 1/30 of the lateral friction (snake3's defaults) that band is
    |phi1 - phi2| < 0.2 or so; outside 0.3 nothing slides."""
    robot = load_robot("snake3")
    bus = SimOptions(robot="snake3", ideal=True).build_bus()
    ids = robot.servo_ids
    drive(bus, dict(zip(ids, robot.angles_to_ticks(np.array([1.1, 0.1])).tolist(), strict=True)))
    bus.run_until(0.005)
    world = World(bus, robot, period=0.01)
    p1 = np.linspace(1.1, -0.9, 101)
    rows = robot.angles_to_ticks(np.column_stack([p1, np.full_like(p1, 0.1)]))
    play_ticks(bus, ids, rows, 0.01)
    rec = world.record()
    assert np.isfinite(rec.pose).all() and np.isfinite(rec.slip).all()
    gap = rec.phi[:, 0] - rec.phi[:, 1]
    closest = np.full(len(rec.t), np.inf)  # nearest approach to the line per interval
    closest[1:] = np.minimum(np.abs(gap[1:]), np.abs(gap[:-1]))
    assert np.abs(rec.slip[closest > 0.3]).max() < 1e-9
    assert np.abs(rec.slip[closest < 0.05]).max() > 0.1


def test_a_robot_whose_servos_are_not_on_the_bus_is_refused():
    robot = load_robot("snake5")
    bus = Bus([VirtualServo(1), VirtualServo(2)])
    with pytest.raises(WorldError, match="no servo with ID 10, 11, 15, 16"):
        World(bus, robot)
