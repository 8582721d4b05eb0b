"""A table plan played on the robot's modelled servos before it is handed out.

The planner makes its table end at the target as the controller plays it on servos that
are where they are told at every frame. Real AX-12s lag a table timed to their speed,
and a plan's loops move the body by the small difference of larger motions, so a lag
that shrinks a loop changes where the plan ends: measured, where the servos come to
rest, the trident's plan to (0.5, 0.2, 10 deg) ends 8.8 times the tolerance off, the
3-link snake's to (2, 1, 20 deg) 8.1 times, on servos under the body's load (3.3 and
9.2 times on the servos' own model, which ignored the load). The plan's table is
therefore also played on the robot's modelled servos in the quasi-static world (the
world ``snakebot sim predict`` and ``sim serve`` play it in, without the physics);
where that end leaves the tolerance the plan says its end played open loop is not to
be trusted, with the numbers (an ``open_loop`` warning)."""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from snakebot.model.plan import Plan
from snakebot.model.plan.planner import Tolerance, pose_dict, pose_error
from snakebot.model.plan.program import ProgramPlan
from snakebot.model.plan.sensitivity import open_loop_warning
from snakebot.model.robots import Robot
from snakebot.workflows.predict import emulate_program, predict_gait


def servo_check(plan: Plan | ProgramPlan) -> dict[str, Any]:
    """``plan``'s table (or program, run by the controller's player) played on the
    robot's modelled servos in the quasi-static world:
    ``servo_check`` (the servo model, where the table ends and its error beside the
    plan's tolerance) and ``warnings`` (an ``open_loop`` one when the end is outside
    the tolerance; a ``not_at_rest`` one when the servos had not stopped), as
    :func:`snakebot.model.plan.files.plan_summary` takes them."""
    robot = plan.robot
    if isinstance(plan, ProgramPlan):
        played = emulate_program("<program>", plan.program, robot)
    else:
        played = predict_gait(plan.gait.gait_table(), robot)
    report, warnings = end_check(
        plan,
        played.emulated.displacement(),
        "servos",
        f"played on the modelled servos ({robot.servo_model})",
        "the servos lag the table, so its end played open loop is not to be trusted",
    )
    warnings = [*played.rest_warnings, *warnings]
    return {"servo_check": {"servos": robot.servo_model, **report}, "warnings": warnings}


class Planned(Protocol):
    """What a check needs of a plan (:class:`Plan`, or a plan made for MuJoCo)."""

    robot: Robot
    target: np.ndarray
    tolerance: Tolerance


def end_check(
    plan: Planned, moved: dict[str, float], cause: str, played: str, why: str
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Where a table ``played`` so, which moved the body by ``moved`` (dx, dy, dtheta),
    ends against ``plan``'s target in the quasi-static world: the report (world, predicted
    end, its error beside the tolerance) and, when the end is outside the tolerance, the
    ``open_loop`` warning of ``cause`` saying ``why`` it matters."""
    end = np.array([moved["dx"], moved["dy"], moved["dtheta"]])
    error = plan.tolerance.report(pose_error(end, plan.target))
    report = {"world": "kinematic", "predicted_final": pose_dict(end), "error": error}
    if error["within"]:
        return report, []
    return report, [end_warning(cause, error, plan.robot, played, why)]


def end_warning(
    cause: str, error: dict[str, Any], robot: Robot, played: str, why: str
) -> dict[str, Any]:
    """The ``open_loop`` warning of a table that, ``played`` so, ends outside the
    tolerance (``error``, a tolerance report), with the numbers and ``why`` it matters."""
    return open_loop_warning(
        cause,
        error,
        lambda position, heading: (
            f"{played} the table ends {error['position']:.3g} {robot.length_unit} from the "
            f"target ({position:.1f}x the position tolerance) and "
            f"{abs(math.degrees(error['heading_rad'])):.2f} deg off its heading "
            f"({heading:.1f}x): {why}; steer in closed loop (goto)"
        ),
    )
