"""Gait search: serpenoid parameters swept (grid), sampled (random) or optimised
(CMA-ES) in either world, on this machine's cores or on a Dask cluster. Its figures are
:mod:`snakebot.plots.search`.

    request = Request(Settings("snake5", "kinematic", 3, 50), Space.parse(("A=10deg:60deg:6", ...)))
    outcome = Search(request, make_runner(None, None)).run()

May import: as the ``workflows`` layer (``sim``, ``link``, ``model``, ``formats``,
``facts``, the package root).
"""

from __future__ import annotations

from snakebot.workflows.search.evaluate import METRICS, Settings, evaluate
from snakebot.workflows.search.runner import DaskRunner, InlineRunner, LocalRunner, make_runner
from snakebot.workflows.search.search import (
    METHODS,
    OBJECTIVES,
    Candidate,
    Outcome,
    Request,
    Search,
)
from snakebot.workflows.search.space import Axis, SearchError, Space

__all__ = [
    "METHODS",
    "METRICS",
    "OBJECTIVES",
    "Axis",
    "Candidate",
    "DaskRunner",
    "InlineRunner",
    "LocalRunner",
    "Outcome",
    "Request",
    "Search",
    "SearchError",
    "Settings",
    "Space",
    "evaluate",
    "make_runner",
]
