"""A table plan's end with half and twice the wheels' rolling resistance (issue #31):
reported for the robots whose motion depends on friction, beside the plan's tolerance."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from snakebot.model.gait import serpenoid
from snakebot.model.gait.common import table_motion
from snakebot.model.plan.files import plan_summary
from snakebot.model.plan.planner import Tolerance
from snakebot.model.plan.sensitivity import (
    ROLLING_FACTORS,
    depends_on_friction,
    friction_sensitivity,
    friction_warning,
)
from snakebot.model.robots import load_robot

SNAKE5, SNAKE3, TRIDENT = load_robot("snake5"), load_robot("snake3"), load_robot("trident")


def plan_like(robot, tolerance: float):
    """A table on ``robot`` aimed exactly where it ends at the robot's own friction (the
    fields friction_sensitivity reads from a plan)."""
    gait = serpenoid(robot, math.radians(30), math.pi, math.pi / 2, cycles=1, rate_hz=20)
    angles = robot.ticks_to_angles(gait.ticks)
    end = table_motion(robot, angles, gait.period_ms / 1000, False, per_interval=2)
    target = end.trajectory.q[-1, :3]
    return SimpleNamespace(
        robot=robot, gait=gait, target=target, tolerance=Tolerance(tolerance, math.radians(2))
    )


def test_only_robots_with_more_wheels_than_body_freedoms_depend_on_friction():
    assert depends_on_friction(SNAKE5)
    assert not depends_on_friction(SNAKE3) and not depends_on_friction(TRIDENT)


def test_half_and_twice_the_rolling_resistance_move_a_five_link_plans_end():
    rows = friction_sensitivity(plan_like(SNAKE5, 5e-4))
    assert [r["rolling_factor"] for r in rows] == list(ROLLING_FACTORS)
    for row in rows:
        f = SNAKE5.friction
        factor = row["rolling_factor"]
        changed = replace(f, rolling=f.rolling * factor, axle_nm=f.axle_nm * factor)
        gait = plan_like(SNAKE5, 5e-4).gait
        played = table_motion(
            SNAKE5,
            SNAKE5.ticks_to_angles(gait.ticks),
            gait.period_ms / 1000,
            False,
            per_interval=2,
            friction=changed,
        )
        np.testing.assert_allclose(
            list(row["predicted_final"].values()), played.trajectory.q[-1, :3]
        )
        assert row["error"]["position"] > 1e-4  # the end moves: the snake is over-constrained
    # the tolerance decides the verdict: a loose one admits both, a tight one neither
    loose = friction_sensitivity(plan_like(SNAKE5, 1.0))
    assert all(r["error"]["within"] for r in loose)
    assert not any(r["error"]["within"] for r in rows)


def test_the_summary_carries_it_for_a_table_on_snake5_only():
    with pytest.MonkeyPatch.context() as m:
        m.setattr("snakebot.model.plan.files.Plan", SimpleNamespace)
        five, three = plan_like(SNAKE5, 0.01), plan_like(SNAKE3, 0.01)
        for p in (five, three):
            p.summary = lambda: {"warnings": []}
        assert len(plan_summary(five)["friction_sensitivity"]) == len(ROLLING_FACTORS)
        assert "friction_sensitivity" not in plan_summary(three)


def test_an_end_outside_the_tolerance_is_an_open_loop_warning_with_its_numbers():
    """The worst end outside the tolerance, as multiples of it; none when all are in."""
    rows = friction_sensitivity(plan_like(SNAKE5, 5e-4))
    warning = friction_warning(rows)
    assert warning is not None and warning["kind"] == "open_loop"
    worst = max(
        max(r["error"]["position"] / 5e-4, abs(r["error"]["heading_rad"]) / math.radians(2))
        for r in rows
    )
    assert max(warning["position_ratio"], warning["heading_ratio"]) == pytest.approx(worst)
    assert f"{warning['position_ratio']:.1f}x" in warning["message"]
    assert friction_warning(friction_sensitivity(plan_like(SNAKE5, 1.0))) is None
