"""The AX-12 actuator model, read from a real virtual servo's registers: compliance margin,
punch and slope, Torque Limit and Moving Speed caps, torque off, wheel mode."""

from __future__ import annotations

import math

import pytest

from snakebot.model.robots import TICKS_PER_RAD
from snakebot.sim.physics.actuator import Actuator
from snakebot.sim.servo import motor
from snakebot.sim.servo.fast import VirtualServo

AX12A = Actuator.for_model("AX-12A")
PUNCH = 32 / 1023  # the factory Punch


def duty(servo: VirtualServo, pos: float) -> tuple[float, float, bool]:
    """(duty the law gives at ``pos``, its cap, whether Torque Limit cut it)."""
    gain, target, bias, cap, cut = AX12A.drive(servo.controller(), pos)
    u = gain * (target - pos) + bias
    return max(-cap, min(cap, u)), cap, cut


@pytest.fixture()
def servo():
    s = VirtualServo(1, "AX-12A", position=512)
    s.set_register("Goal Position", 600)
    s.set_register("Torque Enable", 1)
    return s


def test_inside_the_compliance_margin_the_motor_lets_go(servo):
    for pos in (599, 600, 601):  # factory margins: 1 tick either side
        assert duty(servo, pos)[0] == 0.0


def test_outside_the_margin_the_duty_starts_at_punch_and_rises_over_the_slope(servo):
    # factory slope 32 ticks: half-way up it is half-way from punch to full
    assert duty(servo, 600 - 1 - 16)[0] == pytest.approx(PUNCH + (1 - PUNCH) * 0.5)
    assert duty(servo, 600 + 1 + 16)[0] == pytest.approx(-(PUNCH + (1 - PUNCH) * 0.5))
    assert duty(servo, 600 - 1 - 1e-9)[0] == pytest.approx(PUNCH)
    assert duty(servo, 100)[0] == 1.0  # far away: full drive
    servo.set_register("CCW Compliance Slope", 128)  # a softer servo pushes less
    assert duty(servo, 600 - 1 - 16)[0] == pytest.approx(PUNCH + (1 - PUNCH) / 8)


def test_torque_limit_caps_the_drive_and_says_when_it_cuts(servo):
    servo.set_register("Torque Limit", 511)
    u, cap, cut = duty(servo, 100)
    assert cap == pytest.approx(511 / 1023) and u == cap and cut
    assert not duty(servo, 598)[2]  # a small error asks for less than the limit


def test_moving_speed_caps_the_drive_at_the_duty_of_that_no_load_speed(servo):
    unit = motor.SPEED_UNIT_RPM * motor.TICKS_PER_S_PER_RPM  # ticks/s per Moving Speed unit
    no_load_units = AX12A.no_load_rad_s * TICKS_PER_RAD / unit
    servo.set_register("Moving Speed", round(no_load_units / 2))
    u, cap, cut = duty(servo, 100)
    assert cap == pytest.approx(0.5, abs=0.005) and u == cap
    # the setting cuts the drive as Torque Limit would: a joint the load holds there
    # reports overload (the world's stall timing tells a moving one from a held one)
    assert cut
    servo.set_supply(0.0, 6.0)  # at half the voltage the same speed takes full drive
    assert duty(servo, 100)[1] == pytest.approx(1.0, abs=0.01)


def test_torque_off_or_wheel_mode(servo):
    servo.set_register("Torque Enable", 0)
    assert AX12A.drive(servo.controller(), 100) == (0.0, 0.0, 0.0, 0.0, False)
    servo.set_register("Torque Enable", 1)
    servo.set_register("CW Angle Limit", 0)
    servo.set_register("CCW Angle Limit", 0)  # wheel mode: Moving Speed is the duty
    servo.set_register("Moving Speed", 1024 | 512)  # half, CW
    gain, _, bias, cap, _ = AX12A.drive(servo.controller(), 100)
    assert gain == 0.0 and bias == pytest.approx(-512 / 1023) and cap == 1.0


def test_the_motor_constants_are_the_servo_models():
    spec = motor.spec_for("AX-12A")
    assert AX12A.stall_nm == spec.stall_torque_nm
    assert AX12A.no_load_rad_s == pytest.approx(spec.no_load_rpm * math.pi / 30)
    # the torque-speed line: stall torque at rest, nothing left at the no-load speed
    assert AX12A.stall_at(12.0) - AX12A.damping * AX12A.no_load_rad_s == pytest.approx(0.0)
    assert AX12A.stall_at(spec.nominal_voltage / 2) == pytest.approx(spec.stall_torque_nm / 2)
