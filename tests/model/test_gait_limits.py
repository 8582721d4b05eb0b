"""The limit checks every gait passes before it is written: joint ranges, the servo's
speed, and the table as the controller plays it (including a loop's wrap)."""

import numpy as np
import pytest

from snakebot.model.gait import GaitLimitError, check_motion, check_ticks
from snakebot.model.robots import load_robot

SNAKE3 = load_robot("snake3")  # limits +-90 deg = ticks 205..819, AX-12A 6.18 rad/s


def test_motion_inside_the_limits_passes():
    t = np.linspace(0, 1, 101)
    phi = np.c_[np.sin(t), -np.sin(t)]
    check_motion(SNAKE3, t, phi, np.c_[np.cos(t), -np.cos(t)])


def test_the_earliest_violation_is_reported_with_joint_time_and_limit():
    t = np.linspace(0, 1, 11)
    phi = np.zeros((11, 2))
    phi[7, 0] = 1.7  # above +90 deg at t = 0.7
    dphi = np.zeros((11, 2))
    dphi[4, 1] = -7.0  # too fast at t = 0.4
    with pytest.raises(
        GaitLimitError,
        match=r"joint phi2 \(servo 2\) moves at 7\.00 rad/s at "
        r"t = 0\.400 s, above the AX-12A's maximum of 6\.18 rad/s \(and 1 more",
    ):
        check_motion(SNAKE3, t, phi, dphi)
    with pytest.raises(
        GaitLimitError,
        match=r"joint phi1 \(servo 1\) reaches 97\.4 deg at "
        r"t = 0\.700 s, above its maximum of 90\.0 deg",
    ):
        check_motion(SNAKE3, t, phi, None)


def test_table_checks_ticks_and_frame_to_frame_speed():
    ok = np.array([[512, 512], [530, 500], [548, 490]])
    check_ticks(SNAKE3, ok, 0.02, loop=False)
    with pytest.raises(
        GaitLimitError,
        match=r"frame 1 \(t = 0\.020 s\) sets joint phi2 to tick "
        r"830, outside its limits 205\.\.819",
    ):
        check_ticks(SNAKE3, np.array([[512, 512], [512, 830]]), 0.02, loop=False)
    # 36 ticks in 20 ms is 9.2 rad/s
    with pytest.raises(GaitLimitError, match=r"played frame to frame.*phi1.*9\.21 rad/s"):
        check_ticks(SNAKE3, np.array([[512, 512], [548, 512]]), 0.02, loop=False)


def test_a_loop_is_checked_across_its_wrap():
    frames = np.array([[512, 512], [530, 512], [548, 512]])  # 18 ticks per 20 ms: fine
    check_ticks(SNAKE3, frames, 0.02, loop=False)
    # looping, the last frame (t = 0.04 s) wraps 36 ticks back to frame 0 in one period
    with pytest.raises(GaitLimitError, match=r"t = 0\.040 s"):
        check_ticks(SNAKE3, frames, 0.02, loop=True)
