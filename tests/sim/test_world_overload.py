"""OVERLOAD in both worlds (docs/models.md "The servo's speed limit"): a servo reports it
when it cannot hold its load with the drive it is allowed to give, whichever cap binds
(Torque Limit, or Moving Speed's under the robot file's default speed_limit = "drive"),
once its joint has stayed stalled under that saturated drive for the hold time. A push on
a servo's horn trips it; the gaits a user plays, whose Moving Speed falls to almost
nothing at every turn of the wave, do not. snake5's servos on the real emulated bus, in
the kinematic world's loaded servos and in real MuJoCo."""

from __future__ import annotations

import math

import pytest

from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol.errors import ErrorFlags
from snakebot.link.transport import DxlClient
from snakebot.model.gait import serpenoid
from snakebot.model.robots import load_robot
from snakebot.workflows.demo import DemoSettings
from snakebot.workflows.friction import repeated
from snakebot.workflows.predict import move_to_start, play, sim_url

pytest.importorskip("mujoco")

SNAKE5 = load_robot("snake5")
WORLDS = ("kinematic", "mujoco")
PUSH_NM = 5.0  # well above an AX-12A's 1.5 N m stall torque
PUSHED_S = (1.0, 4.0)  # from, to, in a 6 s play
DEMO = DemoSettings()
# (A deg, delta deg, omega deg/s): the demo's gait and the sweep's corners (docs/thesis.md)
GAITS = {
    "demo": (math.degrees(DEMO.amplitude), math.degrees(DEMO.delta), math.degrees(DEMO.omega)),
    "wide, large step": (40, 150, 180),
    "slow": (30, 60, 90),
    "fast, large step": (30, 150, 360),
}


def gait(amplitude: float, delta: float, omega: float) -> GaitTable:
    """The serpenoid's loop played three times, as the friction study plays it."""
    wave = serpenoid(
        SNAKE5, math.radians(amplitude), math.radians(omega), math.radians(delta), loop=True
    )
    return repeated(wave.gait_table(), 3)


def overloaded(world: str, table: GaitTable, pushed: int | None = None) -> set[int]:
    """The servos that report OVERLOAD after ``table`` played in ``world`` (``pushed``: a
    servo whose horn is pushed with PUSH_NM over PUSHED_S of the play)."""
    client = DxlClient(sim_url(SNAKE5, False), echo=False)
    try:
        bus = client.port.bus
        move_to_start(client, bus, SNAKE5, table.frames[0])
        if pushed is not None:  # while the world runs (the servo's own model trips too)
            servo = bus.servo(pushed)
            for at, torque in zip(PUSHED_S, (PUSH_NM, 0.0), strict=True):
                bus.at(bus.now + at, servo.set_external_torque, torque)
        play(client, bus, SNAKE5, table, ideal=False, world=world)
        errors = {sid: client.ping(sid, check=False).error for sid in SNAKE5.servo_ids}
    finally:
        client.close()
    return {sid for sid, error in errors.items() if error & ErrorFlags.OVERLOAD}


@pytest.mark.parametrize("world", WORLDS)
@pytest.mark.parametrize("name", GAITS)
def test_a_gait_raises_no_overload(world, name):
    assert SNAKE5.speed_limit == "drive"  # Moving Speed's cap binds at the wave's turns
    assert overloaded(world, gait(*GAITS[name])) == set()


@pytest.mark.parametrize("world", WORLDS)
def test_a_push_on_a_horn_raises_overload_on_that_servo_only(world):
    victim = SNAKE5.servo_ids[1]
    assert overloaded(world, gait(*GAITS["demo"]), pushed=victim) == {victim}
