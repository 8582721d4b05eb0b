"""On-board validation of the serpenoid: the controller refuses a wave that leaves a
roster joint's limits or outruns the servo (Refusal Reason AMPLITUDE / SPEED), and a live
change that would do so is refused with RANGE, instead of clipping goals silently."""

from __future__ import annotations

import math

from ctl_support import CTL, CTL_ID, Device, lib_value
from hypothesis import given, settings
from hypothesis import strategies as st

from snakebot.core import ffi, lib
from snakebot.facts.devices import ax12
from snakebot.formats.protocol import ErrorFlags, write
from snakebot.link.controller import ControllerErrors, State
from snakebot.link.controller.playback import SerpenoidSettings, check_serpenoid, roster_from_robot
from snakebot.model.gait.limits import GaitLimitError
from snakebot.model.robots import load_robot

SNAKE5 = load_robot("snake5")
POSITION = ax12().require_position()
MRAD = 1000.0


def mrad(rad: float) -> int:
    return round(rad * MRAD)


def with_snake5(dev: Device) -> None:
    """The roster of snake5 through the servo window, as `snakebot serpenoid --robot`."""
    fields = ("ID", "Reverse", "Zero Tick", "Min Tick", "Max Tick")
    for k, e in enumerate(roster_from_robot(SNAKE5)):
        page, slot = CTL.servo_page(k)
        assert dev.set("Window Page", page) == 0
        values = (e.id, int(e.reverse), e.zero_tick, e.min_tick, e.max_tick)
        data = b"".join(CTL.servo_field(f).encode(v) for f, v in zip(fields, values, strict=True))
        assert dev.one(write(CTL_ID, CTL.servo_address(slot, "ID"), data)).error == 0
    assert dev.set("Joint Count", SNAKE5.n_joints) == 0


def serp(dev: Device, amplitude: float, omega: float, delta: float, offset: float) -> None:
    for name, value in (
        ("Serp Amplitude", mrad(amplitude)),
        ("Serp Omega", mrad(omega)),
        ("Serp Delta", mrad(delta)),
        ("Serp Phi0", mrad(offset)),
    ):
        assert dev.set(name, value) == 0, name


def refusal(dev: Device) -> int:
    assert dev.set("Window Page", CTL.page("Program").number) == 0
    return dev.get("Refusal Reason")


def test_the_issue_reproduction_is_refused_with_its_reason():
    dev = Device()
    with_snake5(dev)
    serp(dev, math.radians(80), 10.0, math.radians(60), math.radians(30))
    assert dev.command("SERPENOID") == 0
    assert dev.state == State.IDLE
    assert dev.flags & ControllerErrors.REFUSED
    assert refusal(dev) == lib_value("Refusal Reason", "AMPLITUDE")
    dev.tick(0)
    assert dev.state == State.IDLE  # nothing moves


def test_a_wave_too_fast_for_the_servo_is_refused():
    dev = Device()
    with_snake5(dev)
    vmax = SNAKE5.max_speed_rad_s
    serp(dev, 0.5, 1.05 * vmax / 0.5, 1.0, 0.0)  # A * omega 5 % above the servo's speed
    assert dev.command("SERPENOID") == 0
    assert refusal(dev) == lib_value("Refusal Reason", "SPEED")
    serp(dev, 0.5, 0.95 * vmax / 0.5, 1.0, 0.0)
    assert dev.command("SERPENOID") == 0
    assert dev.state == State.SERPENOID
    assert refusal(dev) == lib_value("Refusal Reason", "NONE")


def test_live_changes_that_leave_the_limits_are_refused_with_range():
    dev = Device()
    with_snake5(dev)
    serp(dev, 0.5, 4.0, 1.0, 0.0)
    assert dev.command("SERPENOID") == 0 and dev.state == State.SERPENOID
    too_wide = mrad(SNAKE5.joints[0].max_rad) + 10  # two ticks past, beyond rounding
    assert dev.set("Serp Amplitude", too_wide) == ErrorFlags.RANGE
    assert dev.get("Serp Amplitude") == mrad(0.5)
    assert refusal(dev) == lib_value("Refusal Reason", "AMPLITUDE")
    # the speed factor counts too: 4x the 2 rad/s of A * omega is above the servo's
    assert dev.set("Speed Scale", 4 * 256) == ErrorFlags.RANGE
    assert refusal(dev) == lib_value("Refusal Reason", "SPEED")
    steer = CTL.register("Steering Offset")
    assert dev.set("Steering Offset", steer.max) == ErrorFlags.RANGE
    # a change within the limits applies at once, and the wave keeps running
    assert dev.set("Serp Amplitude", mrad(0.6)) == 0
    assert dev.state == State.SERPENOID
    # when stopped, the registers take any value in their range (checked at the start)
    assert dev.command("STOP") == 0
    assert dev.set("Serp Amplitude", too_wide) == 0


def roster_of(limits: list[tuple[int, int, int, int]]):
    roster = ffi.new("play_joint[]", len(limits))
    for k, (zero, reverse, lo, hi) in enumerate(limits):
        roster[k].id, roster[k].reverse = k + 1, reverse
        roster[k].zero, roster[k].min, roster[k].max = zero, lo, hi
    return roster


@settings(max_examples=60, deadline=None)
@given(
    amp=st.integers(0, 1000),  # with |omega| <= 6 rad/s always within the servo's speed
    omega=st.integers(-6000, 6000),
    delta=st.integers(-6283, 6283),
    phi0=st.integers(-600, 600),
    steer=st.integers(-60, 60),
    zero=st.integers(300, 700),
    reverse=st.integers(0, 1),
    span=st.integers(50, 500),
)
def test_an_accepted_wave_never_reaches_a_clamp(
    amp, omega, delta, phi0, steer, zero, reverse, span
):
    """What prog_check_serpenoid accepts, the player runs without clipping: over a whole
    cycle every goal, computed with no clamp at all, lies within the joint's limits."""
    lo, hi = max(0, zero - span), min(POSITION.range[1], zero + span)
    joints = [(zero, reverse, lo, hi), (zero + 10, 1 - reverse, lo, hi)]
    accepted = lib.prog_check_serpenoid(roster_of(joints), 2, amp, omega, phi0, steer, 256)
    if accepted != lib.CTL_REFUSAL_REASON_NONE:
        assert accepted == lib.CTL_REFUSAL_REASON_AMPLITUDE  # never SPEED at these speeds
        return
    free = roster_of([(z, r, 0, POSITION.range[1]) for z, r, _, _ in joints])
    params = ffi.new("play_params *")
    params.speed_scale, params.steering, params.amp_mrad = 256, steer, amp
    params.omega_mrad_s, params.delta_mrad, params.phi0_mrad = omega, delta, phi0
    memory = ffi.new("uint8_t[]", lib.play_state_size())  # kept alive: the cast is no owner
    state = ffi.cast("play_state *", memory)
    lib.play_init(state)
    assert lib.play_start_serpenoid(state, 2, 0)
    period_ms = 2 * math.pi / max(abs(omega) / MRAD, 1e-3) * 1000
    for now in range(0, int(min(period_ms, 20000)) + 10, 7):
        assert lib.play_tick(state, params, free, 2, now) == 2
        for k, (_, _, low, high) in enumerate(joints):
            assert low <= lib.play_out_goal(state, k) <= high


def test_a_roster_change_that_would_clip_the_running_wave_is_refused():
    dev = Device()
    with_snake5(dev)
    serp(dev, 0.5, 4.0, 1.0, 0.0)
    assert dev.command("SERPENOID") == 0 and dev.state == State.SERPENOID
    zero = roster_from_robot(SNAKE5)[0].zero_tick
    top = zero + round(0.5 * POSITION.ticks_per_rad)  # the wave's highest goal on joint 0
    max_tick = CTL.servo_field("Max Tick")
    assert dev.set("Window Page", 0) == 0
    address = CTL.servo_address(0, "Max Tick")
    narrower = max_tick.encode(top - 5)
    assert dev.one(write(CTL_ID, address, narrower)).error == ErrorFlags.RANGE
    assert dev.servo_window(0)[0]["Max Tick"] == roster_from_robot(SNAKE5)[0].max_tick
    assert dev.one(write(CTL_ID, address, max_tick.encode(top + 5))).error == 0
    # stopped, the roster takes any limits again (checked at the next start)
    assert dev.command("STOP") == 0
    assert dev.one(write(CTL_ID, address, narrower)).error == 0
    assert dev.command("SERPENOID") == 0
    assert refusal(dev) == lib_value("Refusal Reason", "AMPLITUDE")


@settings(max_examples=80, deadline=None)
@given(
    amplitude=st.floats(0.05, 1.6),
    omega=st.floats(-12.0, 12.0).filter(lambda w: abs(w) > 0.1),
    offset=st.floats(-1.0, 1.0),
    speed=st.sampled_from([0.5, 1.0, 2.0]),
)
def test_the_host_and_the_controller_agree_away_from_the_boundary(amplitude, omega, offset, speed):
    """`snakebot serpenoid --robot` and the controller decide alike, except within two
    ticks (range) or 1 % (speed) of a limit, where rounding to registers may differ."""
    settings_ = SerpenoidSettings(amplitude, omega, 1.0, offset)
    try:
        check_serpenoid(SNAKE5, settings_, speed=speed)
        host_ok = True
    except GaitLimitError:
        host_ok = False
    roster = roster_of(
        [(e.zero_tick, int(e.reverse), e.min_tick, e.max_tick) for e in roster_from_robot(SNAKE5)]
    )
    scale = round(speed * 256)
    reason = lib.prog_check_serpenoid(
        roster, SNAKE5.n_joints, mrad(amplitude), mrad(omega), mrad(offset), 0, scale
    )
    margin = 2 / POSITION.ticks_per_rad
    reach = abs(offset) + amplitude
    limit = min(min(-j.min_rad, j.max_rad) for j in SNAKE5.joints)
    near_range = abs(reach - limit) < margin
    near_speed = abs(amplitude * abs(omega) * speed / SNAKE5.max_speed_rad_s - 1) < 0.01
    if not (near_range or near_speed):
        assert host_ok == (reason == lib.CTL_REFUSAL_REASON_NONE), (host_ok, reason)
