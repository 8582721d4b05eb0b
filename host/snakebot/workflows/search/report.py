"""What a search gives back besides its results table: the robot it may search, its
summary, and the best gait written as a table ready to upload."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from snakebot.formats.gaittable import write_gait
from snakebot.model.gait import serpenoid
from snakebot.model.robots import Robot, load_robot
from snakebot.workflows.search.search import OBJECTIVES, Outcome, Request
from snakebot.workflows.search.space import SearchError

BEST_SUFFIX = ".best.gait"
"""The best gait goes beside the results table: RESULTS.best.gait."""


def search_robot(name: str) -> Robot:
    """The robot ``name`` names, which must be a snake: the search tries serpenoids."""
    robot = load_robot(name)
    if robot.kind != "snake":
        raise SearchError(
            f"{robot.name} is a {robot.kind}: the search tries serpenoid gaits, which "
            "drive a chain of links; give a snake (snake3, snake5 or a .toml)"
        )
    return robot


def best_gait_path(best: Path | None, results: Path | None) -> Path | None:
    """Where the best gait goes: ``best``, else beside the results table, else nowhere."""
    if best is None and results is not None:
        return results.with_name(results.stem + BEST_SUFFIX)
    return best


def summarise(outcome: Outcome, request: Request, workers: int) -> dict[str, Any]:
    """The search in figures: what it ran, how much, and the best candidate's score."""
    best = outcome.best
    failed = sum(1 for c in outcome.candidates if c.score is None)
    metric, sense = OBJECTIVES[request.objective]
    return {
        "robot": request.settings.robot,
        "world": request.settings.world,
        "method": request.method,
        "objective": request.objective,
        "metric": metric,
        "candidates": len(outcome.candidates),
        "failed": failed,
        "runs_evaluated": outcome.evaluated,
        "runs_reused": outcome.reused,
        "workers": workers,
        "wall_s": round(outcome.wall_s, 3),
        "results": str(request.output) if request.output else None,
        "best": None
        if best is None
        else {"parameters": best.point, metric: sense * (best.score or 0.0)}
        | {
            m: best.runs[0].get(m)
            for m in ("slip_ratio", "torque_nm", "torque_ratio", "lateral_ratio")
            if best.runs and m in best.runs[0]
        },
        "on_edge": outcome.edges(request.space),
    }


def write_best(outcome: Outcome, robot: Robot, request: Request, path: Path) -> bool:
    """Write the best candidate's serpenoid as a gait table at ``path`` (with the
    search's cycles and frame rate); False when no candidate succeeded."""
    best = outcome.best
    if best is None:
        return False
    p = best.point
    g = serpenoid(
        robot,
        p["amplitude"],
        p["omega"],
        p["delta"],
        offset=p["offset"],
        cycles=request.settings.cycles,
        rate_hz=request.settings.rate_hz,
    )
    write_gait(path, g.gait_table())
    return True
