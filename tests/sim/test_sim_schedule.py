"""What the emulator's fast paths must keep true: a repeated call on the bus clock stops
when cancelled (a stopped world leaves nothing behind), the bus finds servos by their
current ID, and register writes take effect at once (the voltage limits included)."""

from __future__ import annotations

import pytest
from sim_support import make_bus, reply

from snakebot.formats import protocol as P
from snakebot.formats.protocol import ErrorFlags
from snakebot.model.robots import load_robot
from snakebot.sim.options import SimOptions
from snakebot.sim.world import World


def test_a_cancelled_schedule_stops_and_leaves_no_event_behind():
    bus = make_bus(1)
    calls: list[float] = []
    schedule = bus.every(0.01, calls.append)
    bus.run_until(0.035)
    assert [round(t, 9) for t in calls] == [0.0, 0.01, 0.02, 0.03]
    schedule.cancel()
    assert bus.next_event_time() is None
    bus.run_until(0.1)
    assert len(calls) == 4


def test_a_schedule_may_cancel_itself_from_its_own_call():
    bus = make_bus(1)
    calls: list[float] = []

    def call(t: float) -> None:
        calls.append(t)
        if len(calls) == 3:
            schedule.cancel()

    schedule = bus.every(0.01, call, start=0.005)
    bus.run_until(1.0)
    assert [round(t, 9) for t in calls] == [0.005, 0.015, 0.025]
    assert bus.next_event_time() is None


def test_a_stopped_world_leaves_the_bus_idle():
    bus = SimOptions.from_query("robot=snake5").build_bus()
    world = World(bus, load_robot("snake5"), period=0.01)
    bus.run_until(0.1)
    world.stop()
    samples = world.samples
    assert samples == 11 and not world.running
    assert bus.next_event_time() is None
    bus.run_until(0.5)
    assert world.samples == samples


def test_positions_follow_a_servo_that_changes_its_id():
    bus = make_bus(1, 2)
    assert bus.positions([2, 1]) == [512.0, 512.0]
    assert reply(bus, P.write(2, 3, b"\x05")).id == 5  # WRITE ID 5 to servo 2
    assert bus.servo(5) is bus.servos[1]
    assert len(bus.positions([5, 1])) == 2
    with pytest.raises(KeyError, match="no servo with ID 2"):
        bus.positions([2])


def test_the_first_of_two_servos_with_one_id_is_the_one_found():
    bus = make_bus(1, 2)
    bus.servos[1].set_register("ID", 1)
    assert bus.servo(1) is bus.servos[0]
    bus.servos[0].set_register("ID", 7)
    assert bus.servo(1) is bus.servos[1] and bus.servo(7) is bus.servos[0]


def test_writing_the_voltage_limits_takes_effect_at_once():
    bus = make_bus(1)  # 12 V supply, limits 6.0-14.0 V
    assert reply(bus, P.ping(1)).error == 0
    answer = reply(bus, P.write(1, 13, bytes([100])))  # Max Voltage Limit 10.0 V
    assert answer.error == ErrorFlags.INPUT_VOLTAGE
    assert reply(bus, P.ping(1)).error == ErrorFlags.INPUT_VOLTAGE
    assert reply(bus, P.write(1, 13, bytes([140]))).error == 0
