"""Serpenoid gait tables: frames follow the formula, the table fits the controller,
limits are enforced before anything is written, and delta = pi goes nowhere."""

import math

import numpy as np
import pytest

from snakebot.errors import SnakebotError
from snakebot.formats.gaittable import max_frames, read_gait, write_gait
from snakebot.model.gait import GaitError, GaitLimitError, serpenoid
from snakebot.model.robots import load_robot

SNAKE5 = load_robot("snake5")


def test_frames_follow_the_formula_and_loop(tmp_path):
    gait = serpenoid(SNAKE5, 0.5, 3.0, 1.2, offset=0.1, cycles=2, rate_hz=50)
    path = tmp_path / "s.gait"
    write_gait(path, gait.gait_table())
    table = read_gait(path)
    omega = gait.parameters["omega_rad_s"]
    steps = len(table.frames)
    assert table.loop and table.frame_period_ms == 20
    assert steps * 0.02 == pytest.approx(2 * 2 * math.pi / omega)  # whole cycles, no repeat
    assert abs(omega - 3.0) <= 3.0 * 0.5 / steps  # adjusted by under half a frame
    t = np.arange(steps) * 0.02
    phi = 0.5 * np.sin(omega * t[:, None] + 1.2 * np.arange(4)) + 0.1
    np.testing.assert_array_equal(table.frames, SNAKE5.angles_to_ticks(phi))
    assert table.joint_ids == SNAKE5.servo_ids
    assert table.limits == SNAKE5.tick_limits
    assert table.metadata["predicted"] == gait.predicted


def test_fractional_cycles_play_once_and_end_on_the_last_sample():
    gait = serpenoid(SNAKE5, 0.4, 2 * math.pi, 1.0, cycles=1.5, rate_hz=20)
    assert not gait.loop
    assert len(gait.ticks) == round(1.5 / 0.05) + 1


def test_table_prediction_tracks_the_continuous_gait():
    gait = serpenoid(SNAKE5, 0.5, 2 * math.pi, math.pi / 2, cycles=3, rate_hz=50)
    assert gait.predicted["dx"] > 0.05  # it crawls forward
    for key in ("dx", "dy"):
        tolerance = 0.02 * gait.predicted["dx"]
        assert gait.table[key] == pytest.approx(gait.predicted[key], abs=tolerance)


@pytest.mark.parametrize("robot", ["snake5", "snake3"])
def test_delta_pi_goes_nowhere(robot):
    gait = serpenoid(load_robot(robot), 0.6, 4.0, math.pi, cycles=2, rate_hz=50)
    for motion in (gait.predicted, gait.table):
        assert abs(motion["dx"]) < 1e-8 and abs(motion["dy"]) < 1e-8
        assert abs(motion["dtheta"]) < 1e-8


def test_range_violation_names_joint_time_and_limit():
    with pytest.raises(GaitLimitError) as err:
        serpenoid(SNAKE5, math.radians(60), 2.0, 0.0, offset=math.radians(40), cycles=1)
    message = str(err.value)
    assert "joint phi1 (servo 10)" in message and "above its maximum of 90.0 deg" in message
    t = float(message.split("at t = ")[1].split(" s")[0])
    # phi1 = 60 sin(2t) + 40 deg first exceeds 90 deg where sin(2t) = 5/6
    assert t == pytest.approx(math.asin(5 / 6) / 2, abs=0.01)


def test_speed_violation_names_the_limit():
    with pytest.raises(
        GaitLimitError,
        match=r"moves at 7\.[45]\d rad/s at t = 0\.000 s, above "
        r"the AX-12A's maximum of 6\.18 rad/s",
    ):
        serpenoid(SNAKE5, 0.75, 10.0, 0.5, cycles=2)


def test_speed_just_inside_the_limit_passes():
    vmax = SNAKE5.max_speed_rad_s
    serpenoid(SNAKE5, 0.5, 0.95 * vmax / 0.5, 0.5, cycles=2, rate_hz=100)


def test_refusals():
    with pytest.raises(GaitError, match="trident"):
        serpenoid(load_robot("trident"), 0.5, 1.0, 1.0, cycles=1)
    with pytest.raises(GaitError, match=f"controller holds at most {max_frames(4)} for 4"):
        serpenoid(SNAKE5, 0.3, 2 * math.pi, 1.0, cycles=50, rate_hz=100)
    with pytest.raises(GaitError, match="positive"):
        serpenoid(SNAKE5, -0.3, 1.0, 1.0, cycles=1)


@pytest.mark.parametrize("robot", ["snake3", "snake5"])
def test_positive_delta_and_omega_move_the_snake_head_first(robot):
    # link 1's heading points from its free end (the tail) along the body to the head
    snake = load_robot(robot)
    gait = serpenoid(snake, 0.5, 2.0, 1.2, cycles=1)
    assert gait.predicted["dx"] > 0
    assert "from the tail end (x, y) towards the head" in gait.summary()["frame"]
    backwards = serpenoid(snake, 0.5, 2.0, -1.2, cycles=1)
    assert backwards.predicted["dx"] < 0


def test_a_near_circular_four_link_gait_is_defined_with_rolling_resistance():
    # delta = -0.006: the joints almost equal, the axles almost concurrent; free-rolling
    # wheels cannot follow (the body velocity has a pole), wheels with rolling resistance
    # slip instead. The table rounds the joints to equal ticks over whole frames: there the
    # four axles are concurrent, the equal rolling resistances balance and the least power
    # is a whole edge of body velocities, whose centre the model takes, and the prediction
    # is steady: a start turned by 1e-9 rad ends at the same pose, turned. (With the solve
    # jumping between the edge's ends by rounding, dopri5 at rtol 1e-10 ran out of steps.)
    from dataclasses import replace

    from snakebot.model.gait.common import table_motion

    free = replace(SNAKE5.friction, rolling=0.0, axle_nm=0.0)
    four = replace(SNAKE5, name="snake4", links=4, joints=SNAKE5.joints[:3], friction=free)
    with pytest.raises(SnakebotError, match="singular"):
        serpenoid(four, math.radians(30), math.pi, -0.006, cycles=1)
    rolling = replace(four, friction=SNAKE5.friction)
    steady = serpenoid(rolling, math.radians(30), math.pi, -0.006, cycles=1)
    # near, not through, a singular configuration
    assert all(w["condition"] is not None for w in steady.warnings)
    angles = rolling.ticks_to_angles(steady.ticks)
    assert (np.ptp(angles, axis=1) == 0).sum() >= 2  # frames with all joints equal
    period = steady.period_ms / 1000
    runs = [
        table_motion(rolling, angles, period, steady.loop, pose0=(0.0, 0.0, turn))
        for turn in (0.0, 1e-9)
    ]
    ends = [run.trajectory.q[-1, :3] for run in runs]
    c, s = math.cos(1e-9), math.sin(1e-9)
    x, y, theta = ends[0]
    np.testing.assert_allclose(  # to the prediction's accuracy (measured: 1e-9)
        ends[1], [c * x - s * y, s * x + c * y, theta + 1e-9], rtol=0, atol=1e-8
    )
    assert abs(x) > 5e-3  # it moves: 8.4 mm backwards in one cycle


def test_table_motion_over_two_passes_composes_one_pass_twice():
    from snakebot.model.gait.common import table_motion

    gait = serpenoid(SNAKE5, 0.5, 3.0, 1.2, cycles=1, rate_hz=50)
    angles, period = SNAKE5.ticks_to_angles(gait.ticks), gait.period_ms / 1000
    one = table_motion(SNAKE5, angles, period, True).trajectory.q[-1, :3]
    two = table_motion(SNAKE5, angles, period, True, passes=2).trajectory.q[-1, :3]
    c, s = math.cos(one[2]), math.sin(one[2])
    composed = one + np.array([c * one[0] - s * one[1], s * one[0] + c * one[1], one[2]])
    np.testing.assert_allclose(two, composed, atol=1e-7)
    # starting a loop a whole pass later changes nothing
    later = table_motion(SNAKE5, angles, period, True, start_s=len(angles) * period)
    np.testing.assert_allclose(later.trajectory.q[-1, :3], one, atol=1e-9)
