"""A plan written out: a gait table (with its metadata file) or, for a ``.prog`` path, a
controller program, and the plan's summary naming what was written."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from snakebot.formats.gaittable import GaitTable, save_table
from snakebot.formats.program.files import write_program
from snakebot.model.plan.planner import Plan, PlanRequest
from snakebot.model.plan.program import ProgramPlan
from snakebot.model.plan.sensitivity import depends_on_friction, friction_sensitivity

PROGRAM_SUFFIX = ".prog"
"""An output path with this suffix asks for a controller program instead of a table."""


def wants_program(output: Path | None) -> bool:
    """Whether a plan written to ``output`` is a controller program."""
    return output is not None and output.suffix == PROGRAM_SUFFIX


def plan_summary(plan: Plan | ProgramPlan) -> dict[str, Any]:
    """``plan``'s summary with the robot's length unit and what it means in metres, and
    for a table on a robot whose motion depends on friction, where it ends with half and
    twice the rolling resistance (``friction_sensitivity``)."""
    robot = plan.robot
    summary = {
        **plan.summary(),
        "length_unit": robot.length_unit,
        "length_legend": robot.length_legend,
    }
    if isinstance(plan, Plan) and depends_on_friction(robot):
        summary["friction_sensitivity"] = friction_sensitivity(plan)
    return summary


def save_plan(plan: Plan | ProgramPlan, output: Path) -> tuple[dict[str, Any], GaitTable | None]:
    """Write ``plan`` to ``output``: its summary (:func:`plan_summary`) with ``file`` (and
    a table's ``metadata_file``), and the table written (None for a program)."""
    summary = plan_summary(plan)
    if isinstance(plan, ProgramPlan):
        write_program(output, plan.program)
        summary["file"] = str(output)
        return summary, None
    table = plan.gait.gait_table()
    summary.update(save_table(output, table))
    return summary, table


def plan_for(output: Path | None, request: PlanRequest) -> Plan | ProgramPlan:
    """The plan of ``request`` to write to ``output``: a program's (:func:`plan_program`)
    for a ``.prog`` path, else a table's (:func:`make_plan`)."""
    from snakebot.model.plan import make_plan
    from snakebot.model.plan.program import plan_program

    return (plan_program if wants_program(output) else make_plan)(request)
