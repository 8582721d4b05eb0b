"""A search: candidates from a grid, a seeded random sample or CMA-ES, each run over the
robustness values, scored by one objective; finished runs of an earlier search into the
same table are reused, not run again.

A candidate's score is its objective at its worst over the robustness values (what it can
be counted on to do); a candidate with any failed run has no score.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from snakebot.errors import quoted
from snakebot.sim.physics.select import check_world
from snakebot.workflows.search.evaluate import Settings
from snakebot.workflows.search.results import (
    finished_runs,
    read_results,
    run_key,
    settings_row,
    write_results,
)
from snakebot.workflows.search.runner import Runner, batches_of
from snakebot.workflows.search.space import MAX_RUNS, SearchError, Space

OBJECTIVES = {
    "distance": ("distance_per_cycle", 1.0),
    "speed": ("speed", 1.0),
    "efficiency": ("efficiency", 1.0),
    "slip": ("slip_ratio", -1.0),
}
"""Objective -> (metric, +1 to maximise or -1 to minimise)."""
METHODS = ("grid", "random", "cma")
PER_RUN_S = {"kinematic": 0.0008, "mujoco": 0.5}
"""Rough cost of one run (s), to size the batches handed to the workers."""
CHECKPOINT_S = 2.0
CMA_SIGMA0 = 0.3
"""CMA-ES's initial step, as a fraction of each parameter's range."""
CMA_FAILED_LOSS = 1e12
"""What CMA-ES is told of a candidate that failed (it ranks, so any large value does)."""

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class Request:
    """What to search: ``samples`` is the number of candidates of a random search and the
    budget of a CMA-ES one (a grid has as many as its axes make)."""

    settings: Settings
    space: Space
    objective: str = "distance"
    method: str = "grid"
    samples: int = 100
    seed: int = 1
    output: Path | None = None
    #: Leave out candidates that need more torque than the servos have or more lateral
    #: force than the floor gives (status "infeasible"); False ranks them like the rest.
    penalise: bool = True

    def check(self) -> None:
        if self.objective not in OBJECTIVES:
            raise SearchError(
                f"unknown objective {quoted(self.objective)}: use one of {', '.join(OBJECTIVES)}"
            )
        check_world(self.settings.world)
        if self.method not in METHODS:
            raise SearchError(
                f"unknown method {quoted(self.method)}: use one of {', '.join(METHODS)}"
            )
        self.space.check_world(self.settings.world)
        if not self.space.varied:
            raise SearchError(
                "nothing to search: give at least one parameter a range LOW:HIGH:COUNT"
            ).about("params")
        if self.method != "grid" and self.samples < 1:
            raise SearchError(f"the samples must be 1 or more, not {self.samples}").about("samples")
        if self.method == "grid":
            for axis in self.space.varied:
                axis.values()  # a grid needs every count
        for axis in self.space.robust:
            axis.values()
        runs = self.space.run_count(self.method, self.samples)
        if runs > MAX_RUNS:
            raise SearchError(
                f"this search would make {runs:,} runs, more than the {MAX_RUNS:,} one search "
                "may (its time and memory grow with them): use fewer values per parameter, "
                "fewer samples or robustness values, or search in stages"
            ).about("params", "samples", "robust")


@dataclass
class Candidate:
    """A serpenoid's parameters, its score (None: a run failed) and its runs."""

    point: dict[str, float]
    score: float | None
    reason: str
    runs: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class Outcome:
    candidates: list[Candidate]
    rows: list[dict[str, Any]]
    evaluated: int
    reused: int
    wall_s: float

    @property
    def best(self) -> Candidate | None:
        scored = [c for c in self.candidates if c.score is not None]
        return max(scored, key=lambda c: c.score) if scored else None  # type: ignore[arg-type, return-value]

    def edges(self, space: Space) -> list[str]:
        """The varied parameters at which the best candidate sits on the searched
        range's edge (its optimum may lie beyond: widen the range)."""
        best = self.best
        if best is None:
            return []
        out = []
        for axis in space.varied:
            value, span = best.point[axis.name], axis.high - axis.low
            if min(abs(value - axis.low), abs(value - axis.high)) <= 1e-9 * max(1.0, abs(span)):
                out.append(axis.name)
        return out


class Search:
    """Runs a Request on a Runner, reusing and extending the results table."""

    def __init__(self, request: Request, runner: Runner, progress: Progress | None = None) -> None:
        request.check()
        self.request = request
        self.runner = runner
        self.progress = progress
        self.metric, self.sense = OBJECTIVES[request.objective]
        out = request.output
        self.done = finished_runs(read_results(out), request.settings, out) if out else {}
        self.rows = list(self.done.values())
        self.evaluated = 0
        self.reused = 0
        self._saved = time.monotonic()
        self._total = 0
        self._count = 0

    # -- running -----------------------------------------------------------------------

    def _runs(self, points: list[dict[str, float]]) -> list[list[dict[str, float]]]:
        robust = self.request.space.robust_points()
        return [[{**p, **r} for r in robust] for p in points]

    def _evaluate(self, points: list[dict[str, float]]) -> list[Candidate]:
        runs = self._runs(points)
        # each run's key made once (a run costs well under a millisecond, its key some
        # 10 us): a row comes back with its run's parameters, so its key is its run's
        keys = [[run_key(r) for r in rs] for rs in runs]
        todo, todo_keys, seen = [], [], set()
        for run, key in zip(
            itertools.chain.from_iterable(runs), itertools.chain.from_iterable(keys), strict=True
        ):
            if key in self.done:
                if key not in seen:
                    self.reused += 1
                    self._tick(1)
            elif key not in seen:
                todo.append(run)
                todo_keys.append(key)
            seen.add(key)
        per_run = PER_RUN_S.get(self.request.settings.world, 0.5)
        batches = batches_of(todo, self.runner, per_run)
        starts = list(itertools.accumulate((len(b) for b in batches), initial=0))
        base = settings_row(self.request.settings)
        for i, rows in self.runner.run(self.request.settings, batches):
            for key, row in zip(todo_keys[starts[i] : starts[i + 1]], rows, strict=True):
                full = {**base, **row}
                self.done[key] = full
                self.rows.append(full)
            self.evaluated += len(rows)
            self._tick(len(rows))
            if time.monotonic() - self._saved > CHECKPOINT_S:
                self.save()
        return [
            self._score(p, [self.done[k] for k in ks]) for p, ks in zip(points, keys, strict=True)
        ]

    def _score(self, point: dict[str, float], rows: list[dict[str, Any]]) -> Candidate:
        passing = ("ok",) if self.request.penalise else ("ok", "infeasible")
        failed = [r for r in rows if r["status"] not in passing]
        if failed:
            return Candidate(point, None, str(failed[0]["reason"]), rows)
        values = [self.sense * float(r[self.metric]) for r in rows]
        if any(math.isnan(v) for v in values):
            return Candidate(point, None, f"no {self.metric} for this run", rows)
        return Candidate(point, min(values), "", rows)

    def _tick(self, n: int) -> None:
        self._count += n
        if self.progress is not None:
            self.progress(self._count, self._total)

    def save(self) -> None:
        if self.request.output is not None:
            write_results(self.request.output, self.rows)
        self._saved = time.monotonic()

    # -- methods -----------------------------------------------------------------------

    def run(self) -> Outcome:
        wall0 = time.perf_counter()
        req = self.request
        space = req.space
        n_robust = len(space.robust_points())
        try:
            if req.method == "cma":
                candidates = self._cma(n_robust)
            else:
                points = self.grid_points() if req.method == "grid" else self.random_points()
                self._total = len(points) * n_robust
                candidates = self._evaluate(points)
        finally:
            self.save()
        return Outcome(
            candidates, self.rows, self.evaluated, self.reused, time.perf_counter() - wall0
        )

    def grid_points(self) -> list[dict[str, float]]:
        axes = [a.values() for a in self.request.space.varied]
        return [self.request.space.point(np.array(v)) for v in itertools.product(*axes)]

    def random_points(self) -> list[dict[str, float]]:
        space = self.request.space
        rng = np.random.default_rng(self.request.seed)
        unit = rng.random((self.request.samples, len(space.varied)))
        return [self._from_unit(u) for u in unit]

    def _from_unit(self, unit: np.ndarray) -> dict[str, float]:
        axes = self.request.space.varied
        return self.request.space.point(
            np.array([a.scale(u) for a, u in zip(axes, unit, strict=True)])
        )

    def _cma(self, n_robust: int) -> list[Candidate]:
        try:
            import cma
        except ImportError:
            raise SearchError(
                "the cma method needs the cma package: pip install 'snakebot[search]'"
            ).about("method") from None
        req = self.request
        dim = len(req.space.varied)
        self._total = req.samples * n_robust
        es = cma.CMAEvolutionStrategy(
            [0.5] * dim,
            CMA_SIGMA0,
            {"bounds": [0.0, 1.0], "seed": req.seed, "maxfevals": req.samples, "verbose": -9},
        )
        candidates: list[Candidate] = []
        while not es.stop() and len(candidates) < req.samples:
            unit = es.ask()
            unit = unit[: req.samples - len(candidates)]
            got = self._evaluate([self._from_unit(np.clip(u, 0.0, 1.0)) for u in unit])
            candidates.extend(got)
            losses = [-c.score if c.score is not None else CMA_FAILED_LOSS for c in got]
            if len(unit) < es.popsize:
                break  # the budget ends mid-generation: nothing left to tell
            es.tell(unit, losses)
        return candidates
