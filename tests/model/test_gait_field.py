"""Field-following gaits: direct fields by constant inputs, brackets by loops over whole
periods, the tolerance met, and the servo limits respected."""

import math

import numpy as np
import pytest

from snakebot.model.gait import GaitError, GaitLimitError, field_gait
from snakebot.model.kinematics import fields
from snakebot.model.robots import load_robot

TRIDENT, SNAKE3 = load_robot("trident"), load_robot("snake3")


def _table_speeds(gait):
    phi = gait.robot.ticks_to_angles(gait.ticks)
    return np.abs(np.diff(phi, axis=0)).max() / (gait.period_ms / 1000)


def test_direct_field_is_followed_exactly():
    gait = field_gait(TRIDENT, "g1", duration=0.5)
    assert gait.predicted["dx"] == pytest.approx(0.5, abs=1e-9)
    assert gait.predicted["dy"] == pytest.approx(0.0, abs=1e-9)
    assert gait.table["dx"] == pytest.approx(0.5, abs=0.01)
    assert _table_speeds(gait) <= TRIDENT.max_speed_rad_s


def test_bracket_loops_move_by_the_second_order_prediction():
    h3 = fields(TRIDENT, np.zeros(6))["h3"]
    errors = []
    for amplitude in (0.03, 0.12):
        gait = field_gait(TRIDENT, "h3", periods=2, amplitude=amplitude)
        moved = np.array(gait.extra["moved_q"])
        expected = np.array(gait.extra["second_order"]["q"])
        np.testing.assert_allclose(expected, 2 * math.pi * amplitude**2 * h3, atol=1e-12)
        errors.append(np.linalg.norm(moved - expected) / np.linalg.norm(expected))
    assert errors[0] < 0.04 and errors[1] > 2 * errors[0]


def test_tolerance_is_met_for_a_combination():
    gait = field_gait(TRIDENT, "2*g1-h3", duration=0.2, tolerance=0.2)
    assert gait.parameters["block_relative_error"] <= 0.2
    # 2 g1 - h3 = e_x at q0: a pure x translation of 0.2
    assert gait.predicted["dx"] == pytest.approx(0.2, rel=0.05)
    assert abs(gait.predicted["dy"]) < 0.01 and abs(gait.predicted["dtheta"]) < 0.01
    assert _table_speeds(gait) <= TRIDENT.max_speed_rad_s


def test_every_block_of_the_written_gait_meets_the_tolerance():
    # A direct segment before each loop: the loops must still start at phase 0, as the
    # block the tolerance was measured on did (they used to start mid-phase).
    gait = field_gait(TRIDENT, "h3+g3", form="world", duration=0.3, tolerance=0.05)
    first = gait.parameters["block_relative_error"]
    assert gait.parameters["blocks"] > 1
    assert first <= 0.05
    assert gait.parameters["block_errors_max"] <= 0.05
    assert gait.parameters["block_errors_max"] == pytest.approx(first, rel=0.2)


def test_snake3_bracket_gait_loops_in_joint_space():
    gait = field_gait(SNAKE3, "h1", periods=3, amplitude=0.15)
    assert gait.loop  # the joints return: the table can repeat
    moved, expected = np.array(gait.extra["moved_q"]), np.array(gait.extra["second_order"]["q"])
    assert np.linalg.norm(moved - expected) / np.linalg.norm(expected) < 0.2
    third = field_gait(SNAKE3, "h2", periods=1, amplitude=0.15)
    moved, expected = np.array(third.extra["moved_q"]), np.array(third.extra["second_order"]["q"])
    assert np.linalg.norm(moved - expected) / np.linalg.norm(expected) < 0.05


def test_refusals():
    with pytest.raises(GaitError, match="a number of periods needs 1 or more"):
        field_gait(TRIDENT, "g1", periods=3)
    with pytest.raises(GaitError, match="not both"):
        field_gait(TRIDENT, "h1", duration=0.1, periods=2)
    with pytest.raises(GaitError, match="no bracket term: give the duration"):
        field_gait(TRIDENT, "g1")
    with pytest.raises(GaitError, match="singular"):
        field_gait(SNAKE3, "g1", duration=0.1, start=(0.2, 0.2))
    with pytest.raises(Exception, match="h4"):
        field_gait(TRIDENT, "h4", periods=1)
    with pytest.raises(GaitLimitError, match="above the AX-12A's maximum"):
        field_gait(TRIDENT, "h1", periods=1, amplitude=0.3, omega=40.0, rate_hz=1000)
    with pytest.raises(
        GaitLimitError,
        match=r"joint phi1 \(servo 1\) reaches -90\.\d deg at "
        r"t = 0\.4\d\d s, below its minimum of -90\.0 deg",
    ):
        # every arm: phi = -2 atan(s) at flow parameter s, sped up to the servos' limit
        field_gait(TRIDENT, "g3", duration=1.5)


@pytest.mark.parametrize("expression", ["2*g1-h3", "g3+2*h1", "g2+h2/2", "g1-h3"])
def test_the_thesis_combinations_work_with_the_defaults(expression):
    gait = field_gait(TRIDENT, expression)
    assert gait.parameters["block_relative_error"] <= 0.05
    assert gait.parameters["block_errors_max"] <= 0.05
    assert gait.parameters["flow_parameter"] > 0


def test_a_duration_too_long_for_the_tolerance_says_which_would_do():
    with pytest.raises(GaitError, match="shorten the duration to about") as info:
        field_gait(TRIDENT, "2*g1-h3", duration=1.0)
    suggested = float(str(info.value).split("to about ")[1].split(",")[0])
    gait = field_gait(TRIDENT, "2*g1-h3", duration=suggested)
    assert gait.parameters["block_relative_error"] <= 0.05
