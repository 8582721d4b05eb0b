"""A plan written out: a gait table (with its metadata file) or, for a ``.prog`` path, a
controller program, and the plan's summary naming what was written."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from snakebot.formats.gaittable import GaitTable, save_table
from snakebot.formats.program.files import write_program
from snakebot.model.plan.cycle_plan import CyclePlan
from snakebot.model.plan.planner import Plan, PlanRequest
from snakebot.model.plan.program import ProgramPlan
from snakebot.model.plan.sensitivity import (
    depends_on_friction,
    friction_sensitivity,
    friction_warning,
)

PROGRAM_SUFFIX = ".prog"
"""An output path with this suffix asks for a controller program instead of a table."""


def wants_program(output: Path | None) -> bool:
    """Whether a plan written to ``output`` is a controller program."""
    return output is not None and output.suffix == PROGRAM_SUFFIX


def plan_summary(
    plan: Plan | CyclePlan | ProgramPlan, checks: dict[str, Any] | None = None
) -> dict[str, Any]:
    """``plan``'s summary with the robot's length unit and what it means in metres; for
    a table on a robot whose motion depends on friction, where it ends with half and
    twice the rolling resistance (``friction_sensitivity``), and a warning when that
    leaves the tolerance; and ``checks``, what else was found out about the plan
    (reports by name, and ``warnings`` that join the plan's)."""
    robot = plan.robot
    summary = {
        **plan.summary(),
        "length_unit": robot.length_unit,
        "length_legend": robot.length_legend,
    }
    warnings = list(summary["warnings"])
    if isinstance(plan, Plan) and depends_on_friction(robot):
        rows = friction_sensitivity(plan)
        summary["friction_sensitivity"] = rows
        warning = friction_warning(rows)
        if warning is not None:
            warnings.append(warning)
    found = dict(checks or {})
    warnings += found.pop("warnings", [])
    return {**summary, **found, "warnings": warnings}


def save_plan(
    plan: Plan | CyclePlan | ProgramPlan, output: Path, checks: dict[str, Any] | None = None
) -> tuple[dict[str, Any], GaitTable | None]:
    """Write ``plan`` to ``output``: its summary (:func:`plan_summary`, with ``checks``)
    with ``file`` (and a table's ``metadata_file``, which keeps the summary's warnings
    and checks too), and the table written (None for a program)."""
    summary = plan_summary(plan, checks)
    if isinstance(plan, ProgramPlan):
        write_program(output, plan.program)
        summary["file"] = str(output)
        return summary, None
    table = plan.gait.gait_table()
    kept = ("warnings", "friction_sensitivity", *(checks or {}))
    table.metadata.update({key: summary[key] for key in kept if key in summary})
    summary.update(save_table(output, table))
    return summary, table


def plan_for(output: Path | None, request: PlanRequest) -> Plan | ProgramPlan:
    """The plan of ``request`` to write to ``output``: a program's (:func:`plan_program`)
    for a ``.prog`` path, else a table's (:func:`make_plan`)."""
    from snakebot.model.plan import make_plan
    from snakebot.model.plan.program import plan_program

    return (plan_program if wants_program(output) else make_plan)(request)
