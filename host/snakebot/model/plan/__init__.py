"""Plans to a target pose (``snakebot plan``): the mathematics of the planner (``planner``,
``se2``, ``loops``, ``learn``, ``serpenoid_goto``) and plans as controller programs
(``program``). Running a plan in closed loop on the emulated robot (``snakebot sim
goto``) is :mod:`snakebot.workflows.goto`.

May import: as the ``model`` layer (the other ``model`` packages, ``formats``, ``facts``,
the package root)."""

from __future__ import annotations

from snakebot.model.plan.loops import PlanError
from snakebot.model.plan.planner import Plan, PlanRequest, Unreachable, body_length, make_plan

__all__ = ["Plan", "PlanError", "PlanRequest", "Unreachable", "body_length", "make_plan"]
