"""Plans to a target pose (``snakebot plan``) and closed loop on the emulated robot
(``snakebot sim goto``): see ``planner`` for the method."""

from __future__ import annotations

from snakebot.model.plan.loops import PlanError
from snakebot.model.plan.planner import Plan, Unreachable, body_length, make_plan

__all__ = ["Plan", "PlanError", "Unreachable", "body_length", "make_plan"]
