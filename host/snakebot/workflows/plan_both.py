"""``snakebot plan --world both``: a table of whole serpenoid cycles for an N-link snake
that ends within the tolerance in the quasi-static world and within twice it in MuJoCo,
played open loop in each (issue 31).

Measured (``docs/goto.md``): the two worlds agree on a steady serpenoid cycle (its
length and its turn per radian of offset) to a few per cent at a lag of 90..120 degrees
between joints, 20 % apart at ``serpenoid_goto``'s 150; they part most where the wave
starts and stops at an offset and where it reverses, and the part grows with the way
played. So the routes are ``--world mujoco``'s kind (whole cycles, one offset each,
forwards or backwards, here without reversals), the shortest way first, and their offsets
and lag are solved for both ends at once:

1. the routes: for each lag in ``DELTAS`` the fewest cycles that reach the target by the
   car model of one cycle (its length measured in the quasi-static world), tried in the
   order of the way they play (cycles times length);
2. the quasi-static world alone first: Levenberg-Marquardt on the offsets and the lag,
   its Jacobian by differences (a play there costs a few milliseconds);
3. then both worlds: Levenberg-Marquardt on both ends' errors in tolerances, MuJoCo's
   weighed so that least squares shares the worlds' difference as the bounds do; the
   quasi-static Jacobian by differences at every step, MuJoCo's by differences (one play
   a column), updated by Broyden's method after every step and taken afresh after a step
   that came no nearer;
4. a route whose steps shrink to nothing, or that has had ``ROUTE_PLAYS`` plays, gives
   way to the next.

It stops at the first table within both bounds, or after ``MAX_PLAYS_BOTH`` MuJoCo plays;
then nothing is written and the command exits with status 1, naming the nearest table's
errors in both worlds."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snakebot.model.gait.common import table_motion
from snakebot.model.plan import PlanRequest, se2
from snakebot.model.plan.cycle_plan import (
    MAX_PLAYS_BOTH,
    CyclePlan,
    CycleRoute,
    cycle_gait,
    first_cycles,
    require_serpentine,
    route_ticks,
)
from snakebot.model.plan.loops import PlanError
from snakebot.model.plan.planner import Tolerance, out_of_reach, pose_dict, pose_error
from snakebot.model.plan.serpenoid_goto import (
    MAX_OFFSET,
    CycleModel,
    Wave,
    link1_from_middle,
    middle,
)
from snakebot.workflows.plan_mujoco import (
    displacement_array,
    error_in_tolerances,
    miss_in_tolerances,
)
from snakebot.workflows.predict import predict_gait

WORLD = "both"
#: MuJoCo's end may be this many tolerances off (issue 31: twice).
MUJOCO_BOUND = 2.0
#: MuJoCo's residual's weight beside the quasi-static one's (see ``_Table.stacked``).
WEIGHT = math.sqrt(1.0 / MUJOCO_BOUND)
#: The waves' lags between joints a route starts from (a cycle of 80 degrees carries
#: snake5 about 0.4 m, of 150 degrees 0.08 m), and how far the solve may move it.
DELTAS = tuple(math.radians(d) for d in range(80, 151, 10))
DELTA_RANGE = math.radians(15.0)
#: The step of the quasi-static Jacobian's differences (rad): a few of the servos' ticks.
STEP = 0.01
#: The step of MuJoCo's Jacobian's differences (rad): its end moves in steps of ticks.
MUJOCO_STEP = 0.02
#: The largest step of the solve in any offset or in the lag (rad), at first, and the
#: step below which a route has stalled.
TRUST = 0.1
MIN_TRUST = 0.005
#: Levenberg-Marquardt's damping, in tolerances squared.
DAMPING = 0.1
#: Steps of the quasi-static solve before MuJoCo is played.
QS_STEPS = 12
#: Routes reverse at most this often: a reversal is where the worlds part most.
REVERSALS = 0
#: How near the quasi-static solve comes to its aim, in tolerances.
AIM = 0.2
#: The most MuJoCo plays of one route before the next is tried.
ROUTE_PLAYS = 20


@dataclass
class _Table:
    """One candidate table: its route, its gait and its ends in both worlds (residuals in
    tolerances; ``mujoco`` None until it is played there)."""

    route: CycleRoute
    gait: Any
    quasi_static: np.ndarray
    end_qs: np.ndarray
    mujoco: np.ndarray | None = None
    end_mj: np.ndarray | None = None

    @property
    def merit(self) -> float:
        """The larger of the two ends' errors as shares of their bounds."""
        qs = miss_in_tolerances(self.quasi_static)
        if self.mujoco is None:
            return qs
        return max(qs, miss_in_tolerances(self.mujoco) / MUJOCO_BOUND)

    def stacked(self) -> np.ndarray:
        """Both residuals, MuJoCo's weighed so that least squares shares the worlds'
        difference b as the bounds do: for a fixed b, |e|^2 + |e + b|^2 / 2 is least at
        e = -b / 3, where each end misses by a third of b of its bound."""
        assert self.mujoco is not None
        return np.r_[self.quasi_static, self.mujoco * WEIGHT]


class _Solver:
    """Plays tables in both worlds and keeps the nearest one."""

    def __init__(self, request: PlanRequest, goal: np.ndarray, tol: Tolerance, mu: float | None):
        self.request, self.goal, self.tol, self.mu = request, goal, tol, mu
        self.plays = 0
        self.best: _Table | None = None
        self.centre = DELTAS[0]  # the lag the route being solved started from

    def quasi_static(self, route: CycleRoute) -> _Table | None:
        """The route's table and its end in the quasi-static world (None outside the
        joints' limits)."""
        robot = self.request.robot
        try:
            ticks, period_ms = route_ticks(robot, route, self.request.capacity)
        except PlanError:
            return None
        gait = cycle_gait(robot, route, ticks, period_ms)
        moved = gait.predicted
        end = displacement_array(moved)
        return _Table(route, gait, error_in_tolerances(end, self.goal, self.tol), end)

    def mujoco(self, table: _Table) -> _Table:
        played = predict_gait(
            table.gait.gait_table(), self.request.robot, world="mujoco", mu=self.mu
        )
        self.plays += 1
        moved = played.emulated.displacement()
        table.end_mj = displacement_array(moved)
        table.mujoco = error_in_tolerances(table.end_mj, self.goal, self.tol)
        if self.best is None or table.merit < self.best.merit:
            self.best = table
        return table

    @property
    def within(self) -> bool:
        return self.best is not None and self.best.merit <= 1.0

    def jacobian(self, table: _Table) -> np.ndarray | None:
        """The quasi-static end against the offsets and the lag, by forward differences."""
        return _jacobian(self, table, table.quasi_static, STEP, lambda t: t.quasi_static)

    def low(self, n: int) -> np.ndarray:
        return np.r_[[-MAX_OFFSET] * (n - 1), self.centre - DELTA_RANGE]

    def high(self, n: int) -> np.ndarray:
        return np.r_[[MAX_OFFSET] * (n - 1), self.centre + DELTA_RANGE]

    def step(self, table: _Table, jac: np.ndarray, r: np.ndarray, trust: float) -> _Table | None:
        """The damped least-squares step from ``table`` for the residual ``r`` of
        Jacobian ``jac``, no longer than ``trust`` in any value, within the bounds."""
        x = table.route.values
        step = -np.linalg.solve(jac.T @ jac + DAMPING * np.eye(len(x)), jac.T @ r)
        if np.abs(step).max() > trust:
            step *= trust / np.abs(step).max()
        new = np.clip(x + step, self.low(len(x)), self.high(len(x)))
        if not np.abs(new - x).max() > 0:
            return None
        return self.quasi_static(table.route.with_values(new[:-1], new[-1]))


def _solve_quasi_static(solver: _Solver, table: _Table) -> _Table:
    """Levenberg-Marquardt on the quasi-static end alone (no MuJoCo play), until it is
    within ``AIM`` tolerances."""
    trust = TRUST
    for _ in range(QS_STEPS):
        r = table.quasi_static
        if miss_in_tolerances(r) <= AIM or trust < MIN_TRUST:
            break
        jac = solver.jacobian(table)
        if jac is None:
            break
        new = solver.step(table, jac, r, trust)
        if new is not None and miss_in_tolerances(new.quasi_static) < miss_in_tolerances(r):
            table = new
        else:
            trust *= 0.5
    return table


def _mujoco_jacobian(solver: _Solver, table: _Table) -> np.ndarray | None:
    """MuJoCo's end against the offsets and the lag, by forward differences of
    ``MUJOCO_STEP`` (one play a column)."""
    assert table.mujoco is not None
    return _jacobian(solver, table, table.mujoco, MUJOCO_STEP, lambda t: solver.mujoco(t).mujoco)


def _jacobian(
    solver: _Solver,
    table: _Table,
    base: np.ndarray,
    step: float,
    residual: Callable[[_Table], np.ndarray | None],
) -> np.ndarray | None:
    """A residual (``base`` at ``table``) against the offsets and the lag, by forward
    differences of ``step`` (backwards at the upper bound); None where a moved table
    leaves the joints' limits."""
    x = table.route.values
    high = solver.high(len(x))
    columns = []
    for i in range(len(x)):
        moved = x.copy()
        moved[i] += step if x[i] + step <= high[i] else -step
        other = solver.quasi_static(table.route.with_values(moved[:-1], moved[-1]))
        if other is None:
            return None
        r = residual(other)
        assert r is not None
        columns.append(_difference(r, base, solver.tol) / (moved[i] - x[i]))
    return np.array(columns).T


def _difference(a: np.ndarray, b: np.ndarray, tol: Tolerance) -> np.ndarray:
    """Residual ``a`` less ``b`` (in tolerances), the heading's difference wrapped."""
    d = a - b
    d[2] = (d[2] * tol.heading + math.pi) % (2 * math.pi) - math.pi
    d[2] /= tol.heading
    return d


def _solve_both(solver: _Solver, table: _Table, plays: int) -> None:
    """Levenberg-Marquardt on both ends at once (the residual: the quasi-static end's
    error in tolerances beside MuJoCo's weighed by ``WEIGHT``, ``_Table.stacked``), both
    Jacobians by differences, MuJoCo's updated by Broyden's method after every step and
    taken afresh after a step that failed, until ``plays`` MuJoCo plays are spent."""
    stop = solver.plays + plays
    table = solver.mujoco(table)
    n = len(table.route.offsets) + 1
    jac_mj = None
    trust = TRUST
    while not solver.within and trust >= MIN_TRUST:
        if jac_mj is None:
            if solver.plays + n + 1 > stop:
                return
            jac_mj = _mujoco_jacobian(solver, table)
            if jac_mj is None or solver.within:
                return
        jac_qs = solver.jacobian(table)
        if jac_qs is None or solver.plays >= stop:
            return
        jac = np.vstack([jac_qs, jac_mj * WEIGHT])
        new = solver.step(table, jac, table.stacked(), trust)
        if new is None:
            return
        new = solver.mujoco(new)
        assert new.mujoco is not None and table.mujoco is not None
        dx = new.route.values - table.route.values
        seen = _difference(new.mujoco, table.mujoco, solver.tol)
        jac_mj = jac_mj + np.outer(seen - jac_mj @ dx, dx) / (dx @ dx)
        if new.stacked() @ new.stacked() < table.stacked() @ table.stacked():
            table = new
            trust = min(2 * trust, TRUST)
        else:
            trust *= 0.5
            jac_mj = None


def plan_in_both(
    request: PlanRequest, plays: int = MAX_PLAYS_BOTH, mu: float | None = None
) -> CyclePlan:
    """A cycle plan for ``request`` whose table ends within the tolerance in the
    quasi-static world and within ``MUJOCO_BOUND`` times it in MuJoCo (wheel-floor
    friction ``mu``, default the robot's); Unreachable when ``plays`` MuJoCo plays find
    none."""
    robot = request.robot
    require_serpentine(robot, "both worlds")
    goal, phi0, tol = request.checked()
    start = tuple(float(v) for v in phi0)
    solver = _Solver(request, goal, tol, mu)
    for delta, found in _routes(solver, start):
        if solver.within or solver.plays >= plays:
            break
        solver.centre = delta
        table = solver.quasi_static(CycleRoute(start, found.ways, found.offsets, delta))
        if table is None:
            continue
        table = _solve_quasi_static(solver, table)
        _solve_both(solver, table, min(ROUTE_PLAYS, plays - solver.plays))
    best = solver.best
    if best is None or not solver.within:
        raise _not_met(solver)
    assert best.end_mj is not None
    plan = BothPlan(
        robot,
        goal,
        tol,
        best.route,
        best.gait,
        best.end_qs,
        request.capacity,
        WORLD,
        solver.plays,
        mujoco_end=best.end_mj,
    )
    best.gait.extra.update(plan.summary())
    return plan


def _routes(solver: _Solver, start: tuple[float, ...]) -> list[tuple[float, Any]]:
    """The routes to solve, shortest way first: for each lag in ``DELTAS`` the fewest
    cycles that reach the target by the car model of a cycle of that lag (its length
    measured in the quasi-static world). The worlds part by a share of the way played,
    so a short way of few long cycles beats many short ones."""
    robot, goal, tol = solver.request.robot, solver.goal, solver.tol
    routes = []
    for delta in DELTAS:
        wave = Wave(robot, delta=delta)
        wave.check()
        length = _straight_cycle(solver, start, delta)
        car = CycleModel.from_geometry(robot, length)
        here = middle(robot, wave.angles_at(0.0, 0.0))
        link1 = link1_from_middle(wave, np.zeros(robot.n_joints))
        found = first_cycles(car, here, goal, tol, link1, 1, REVERSALS)
        if found.ways:
            routes.append((len(found.ways) * length, delta, found))
    return [(delta, found) for _, delta, found in sorted(routes, key=lambda r: r[0])]


def _straight_cycle(solver: _Solver, start: tuple[float, ...], delta: float) -> float:
    """How far one straight cycle of lag ``delta`` carries the body's middle in the
    quasi-static world (three cycles played, the middle read at the phase 0 of the
    second and the last)."""
    robot = solver.request.robot
    route = CycleRoute(start, (1.0,) * 3, (0.0,) * 3, delta)
    table = solver.quasi_static(route)
    assert table is not None
    period_s = table.gait.period_ms / 1000.0
    played = table_motion(
        robot, robot.ticks_to_angles(table.gait.ticks), period_s, False, per_interval=2
    ).trajectory
    frames = route.cycle_frames(robot)
    mids = []
    for f in (frames[1], frames[-1]):
        k = int(np.argmin(np.abs(played.t - f * period_s)))
        mids.append(se2.compose(played.q[k, :3], middle(robot, played.q[k, 3:])))
    return float(np.hypot(*se2.relative(mids[0], mids[1])[:2])) / (len(frames) - 2)


@dataclass
class BothPlan(CyclePlan):
    """A cycle plan made for both worlds: ``reached`` is its end in the quasi-static
    world (its claim), ``mujoco_end`` where MuJoCo plays the table to."""

    mujoco_end: np.ndarray = field(default_factory=lambda: np.zeros(3))


def both_check(plan: BothPlan) -> dict[str, Any]:
    """Where ``plan``'s table ends in each world, beside its bound there: the
    quasi-static world's tolerance (``quasi_static``) and MuJoCo's ``MUJOCO_BOUND``
    times it (``mujoco``)."""
    tol = plan.tolerance
    bound = Tolerance(MUJOCO_BOUND * tol.position, MUJOCO_BOUND * tol.heading)
    return {
        "quasi_static": {
            "world": "kinematic",
            "predicted_final": pose_dict(plan.reached),
            "error": plan.tolerance.report(plan.error),
        },
        "mujoco": {
            "world": "mujoco",
            "predicted_final": pose_dict(plan.mujoco_end),
            "error": bound.report(pose_error(plan.mujoco_end, plan.target)),
            "bound": MUJOCO_BOUND,
        },
    }


def _not_met(solver: _Solver) -> Exception:
    robot = solver.request.robot
    best = solver.best
    if best is None or best.mujoco is None:
        return out_of_reach(
            f"no serpenoid plan for {robot.name} was found to play in both worlds",
            solver.request.capacity,
            "choose a nearer target",
            "steer in closed loop (sim goto)",
            params=("target",),
        )
    qs, mj = best.quasi_static, best.mujoco
    return out_of_reach(
        f"no {robot.name} plan of serpenoid cycles met both bounds in {solver.plays} MuJoCo "
        f"plays: the nearest ends {math.hypot(qs[0], qs[1]):.2f}x, {abs(qs[2]):.2f}x the "
        f"tolerance (position, heading) in the quasi-static world and "
        f"{math.hypot(mj[0], mj[1]):.2f}x, {abs(mj[2]):.2f}x in MuJoCo (bounds 1x and "
        f"{MUJOCO_BOUND:g}x)",
        solver.request.capacity,
        "plan for one world (the kinematic or the mujoco world)",
        "steer in closed loop (sim goto)",
        params=("world", "tolerance", "target"),
    )
