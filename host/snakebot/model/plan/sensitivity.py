"""How a table plan's end depends on the wheels' rolling resistance (issue #31).

A snake with more than three wheels has more wheel constraints than body freedoms, so
how far it goes depends on how its wheels share the slip, which the quasi-static model
works out from the friction coefficients; a lab floor gives those only roughly. The plan
is played again with the rolling resistance (the rolling coefficient and the axle's
friction together) halved and doubled, and each end is compared with the target and the
plan's tolerance. The trident and the 3-link snake have as many wheels as body freedoms:
away from singular configurations their motion does not depend on friction, so they are
not checked.

Where an end leaves the tolerance the plan cannot know where its table ends on a real
floor: :func:`friction_warning` says so, with the numbers (an ``open_loop`` warning,
which the plan's report carries beside the others; :func:`open_loop_warning` makes
every warning of that kind)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from snakebot.model.gait.common import table_motion
from snakebot.model.plan.planner import Plan, pose_dict, pose_error
from snakebot.model.robots import Robot

OPEN_LOOP = "open_loop"
"""The kind of a plan's warning that its table, played open loop, may not end within
the tolerance (the JSON reports' ``warnings``)."""

ROLLING_FACTORS = (0.5, 2.0)
"""The rolling resistance the plan is played again with, as factors of the robot's."""


def depends_on_friction(robot: Robot) -> bool:
    """Whether the robot's motion depends on its friction coefficients: more wheels
    than the body's three freedoms."""
    return robot.n_wheels > 3


def friction_sensitivity(plan: Plan) -> list[dict[str, Any]]:
    """For each of :data:`ROLLING_FACTORS`: the factor, where the plan's table then ends
    (``predicted_final``) and its ``error`` beside the plan's tolerance."""
    robot, gait = plan.robot, plan.gait
    angles = robot.ticks_to_angles(np.asarray(gait.ticks))
    rows = []
    for factor in ROLLING_FACTORS:
        f = robot.friction
        changed = replace(f, rolling=f.rolling * factor, axle_nm=f.axle_nm * factor)
        played = table_motion(
            robot, angles, gait.period_ms / 1000.0, False, per_interval=2, friction=changed
        )
        end = played.trajectory.q[-1, :3]
        rows.append(
            {
                "rolling_factor": factor,
                "predicted_final": pose_dict(end),
                "error": plan.tolerance.report(pose_error(end, plan.target)),
            }
        )
    return rows


def tolerance_ratios(error: dict[str, Any]) -> tuple[float, float]:
    """An ``error`` report's position and heading as multiples of their tolerances."""
    return (
        error["position"] / error["position_tolerance"],
        abs(error["heading_rad"]) / error["heading_tolerance_rad"],
    )


def friction_warning(rows: list[dict[str, Any]]) -> dict[str, Any] | None:
    """An ``open_loop`` warning when one of :func:`friction_sensitivity`'s ends is
    outside the tolerance (the worst one, as multiples of the tolerance); None when
    every end is within it."""
    outside = [row for row in rows if not row["error"]["within"]]
    if not outside:
        return None
    worst = max(outside, key=lambda row: max(tolerance_ratios(row["error"])))
    factor = worst["rolling_factor"]
    return open_loop_warning(
        "friction",
        worst["error"],
        lambda position, heading: (
            f"with {factor:g}x the rolling resistance the table ends {position:.1f}x the "
            f"position tolerance and {heading:.1f}x the heading tolerance from the target: "
            "played open loop its end depends on the floor more than the tolerance allows, "
            "so it is not to be trusted; steer in closed loop (goto), or set the robot "
            "file's [friction] for the floor"
        ),
        rolling_factor=factor,
    )


def open_loop_warning(
    cause: str, error: dict[str, Any], says: Callable[[float, float], str], **details: Any
) -> dict[str, Any]:
    """An ``open_loop`` warning: played open loop, the table ends outside the plan's
    tolerance (``error``, a tolerance report) because of ``cause``. It carries
    ``details``, the position and heading errors as multiples of their tolerances, and
    the message ``says`` words from those two multiples."""
    position, heading = tolerance_ratios(error)
    return {
        "kind": OPEN_LOOP,
        "cause": cause,
        **details,
        "position_ratio": position,
        "heading_ratio": heading,
        "message": says(position, heading),
    }
