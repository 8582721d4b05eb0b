"""``snakebot plan --world mujoco``: a table of whole serpenoid cycles for an N-link
snake, shot in MuJoCo until, played open loop there, it ends within the tolerance.

Measured (``docs/goto.md``): the table planner's loops, played open loop in MuJoCo, end
snake5 48 to 600 tolerances from the target; its serpenoid moves it like a car there,
smoothly in the offsets (a tick of offset moves the end by a millimetre or two). So:

1. the route: the fewest whole cycles of ``serpenoid_goto``'s wave that reach the
   target by its car model of one cycle (the closed loop's prior), as ``sim goto``
   plans them (:class:`snakebot.model.plan.cycle_plan.CycleRoute`);
2. the first plays teach the model: the table is played in MuJoCo, each cycle's motion
   of the body's middle is read from the world's record and added to the model, and the
   offsets are fitted again for the target corrected by the miss of the end beside the
   model's (up to ``LEARN_PLAYS``);
3. then shooting by Broyden's method: the end's error (in tolerances) against the
   offsets and ``delta`` (the lag between joints, which sets the length of a cycle),
   the Jacobian first from the model and one play with ``delta`` changed, then updated
   from every play; each step a damped least-squares step from the best table so far.

It stops at the first table that ends within the tolerance in MuJoCo, or after
``MAX_PLAYS`` plays, when the nearest one is reported as not converged (Unreachable).
Every play is deterministic (the bus's clock paces the world), so ``snakebot sim predict
PLAN.gait --world mujoco`` ends where the plan says. The plan is for MuJoCo's body and
floor: the report says so (``world``) and gives where the same table ends in the
quasi-static world, which warns (``open_loop``) when that is outside the tolerance."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from snakebot.model.plan import PlanRequest, se2
from snakebot.model.plan.cycle_plan import (
    DELTA_RANGE,
    MAX_PLAYS,
    ROUTE_ACCEPT,
    CyclePlan,
    CycleRoute,
    cycle_gait,
    first_cycles,
    require_serpentine,
    route_ticks,
)
from snakebot.model.plan.planner import (
    Tolerance,
    body_length,
    out_of_reach,
    pose_error,
)
from snakebot.model.plan.serpenoid_goto import (
    DELTA,
    HORIZON,
    MAX_OFFSET,
    PRIOR_DISTANCE,
    CycleModel,
    Wave,
    end_of,
    fit_offsets,
    link1_from_middle,
    middle,
)
from snakebot.model.robots import Robot
from snakebot.workflows.plan_check import end_check
from snakebot.workflows.predict import Prediction, predict_gait

WORLD = "mujoco"
#: Plays that teach the car model before shooting takes over.
LEARN_PLAYS = 3
#: The step in ``delta`` of the play that measures its column of the Jacobian (rad).
DELTA_STEP = 0.05
#: The largest step of the shooting in any offset or in ``delta`` (rad), at first.
TRUST = 0.1
#: The most plays of one route's shooting, and the step below which it has stalled.
ROUTE_PLAYS = 14
MIN_TRUST = 0.01
#: Damping of the shooting's least-squares step, in tolerances squared.
DAMPING = 0.1


def error_in_tolerances(end: np.ndarray, goal: np.ndarray, tol: Tolerance) -> np.ndarray:
    """The end's error in tolerances: x, y and heading."""
    h = (end[2] - goal[2] + math.pi) % (2 * math.pi) - math.pi
    return np.array(
        [(end[0] - goal[0]) / tol.position, (end[1] - goal[1]) / tol.position, h / tol.heading]
    )


def displacement_array(moved: dict[str, float]) -> np.ndarray:
    """A play's displacement (``dx``, ``dy``, ``dtheta``) as an array."""
    return np.array([moved["dx"], moved["dy"], moved["dtheta"]])


def miss_in_tolerances(r: np.ndarray) -> float:
    """The larger of the position and heading errors of ``r``, in tolerances."""
    return float(max(math.hypot(r[0], r[1]), abs(r[2])))


class _Shooter:
    """Plays routes in MuJoCo and keeps the nearest one."""

    def __init__(self, request: PlanRequest, goal: np.ndarray, tol: Tolerance, mu: float | None):
        self.request, self.goal, self.tol, self.mu = request, goal, tol, mu
        self.plays = 0
        self.best: tuple[float, CycleRoute, np.ndarray, np.ndarray, Any] | None = None
        self.nearest: dict[tuple[float, ...], tuple[CycleRoute, np.ndarray]] = {}

    def play(self, route: CycleRoute) -> tuple[np.ndarray, Prediction]:
        robot = self.request.robot
        ticks, period_ms = route_ticks(robot, route, self.request.capacity)
        gait = cycle_gait(robot, route, ticks, period_ms)
        played = predict_gait(gait.gait_table(), robot, world=WORLD, mu=self.mu)
        self.plays += 1
        moved = played.emulated.displacement()
        end = displacement_array(moved)
        r = error_in_tolerances(end, self.goal, self.tol)
        if self.best is None or miss_in_tolerances(r) < self.best[0]:
            self.best = (miss_in_tolerances(r), route, end, r, gait)
        known = self.nearest.get(route.ways)
        if known is None or miss_in_tolerances(r) < miss_in_tolerances(known[1]):
            self.nearest[route.ways] = (route, r)
        return r, played

    def best_of(self, ways: tuple[float, ...]) -> tuple[CycleRoute, np.ndarray] | None:
        """The nearest play of routes driven ``ways``: the route and its error."""
        return self.nearest.get(ways)

    @property
    def within(self) -> bool:
        return self.best is not None and self.tol.admits(pose_error(self.best[2], self.goal))


def _learn(model: CycleModel, robot: Robot, route: CycleRoute, played: Prediction) -> None:
    """Each cycle's motion of the body's middle, as the world recorded it, into ``model``."""
    record = played.emulated
    period_s = played.table.frame_period_ms / 1000.0
    times = record.t - record.t[0]
    mids = []
    for frame in route.cycle_frames(robot):
        k = int(np.argmin(np.abs(times - frame * period_s)))
        mids.append(se2.compose(record.pose[k], middle(robot, record.phi[k])))
    last = 0.0
    for c, (way, q) in enumerate(zip(route.ways, route.offsets, strict=True)):
        model.add(q, last, way, se2.relative(mids[c], mids[c + 1]))
        last = q


@dataclass
class _Car:
    """The car model of one cycle and what it plans from: the body's middle at the wave's
    start (``here``) and link 1 placed from the middle (``link1``)."""

    model: CycleModel
    here: np.ndarray
    link1: Any

    def end(self, ways: tuple[float, ...], x: np.ndarray) -> np.ndarray:
        return np.array(end_of(self.model, self.here, 0.0, ways, x, self.link1))

    def jacobian(self, ways: tuple[float, ...], x: np.ndarray, tol: Tolerance) -> np.ndarray:
        """The end against the offsets, in tolerances per radian (differences)."""
        base = self.end(ways, x)
        columns = []
        for i in range(len(x)):
            step = np.zeros(len(x))
            step[i] = 1e-4
            d = self.end(ways, x + step) - base
            d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
            columns.append(d / 1e-4 / np.array([tol.position, tol.position, tol.heading]))
        return np.array(columns).T

    def route(
        self, goal: np.ndarray, tol: Tolerance, least: int = 1
    ) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
        """:func:`first_cycles`' ways and offsets, of ``least`` cycles or more."""
        found = first_cycles(self.model, self.here, goal, tol, self.link1, least)
        return None if not found.ways else (found.ways, found.offsets)


def _teach(shooter: _Shooter, car: _Car, route: CycleRoute, plays: int) -> CycleRoute:
    """Up to ``plays`` plays of ``route``, each teaching the car model every cycle's
    motion, then fitted again by the model for the target corrected by the end's miss
    beside the model's; the route to shoot from."""
    robot, goal, tol = shooter.request.robot, shooter.goal, shooter.tol
    for _ in range(plays):
        _, played = shooter.play(route)
        if shooter.within:
            break
        _learn(car.model, robot, route, played)
        x = np.array(route.offsets)
        moved = played.emulated.displacement()
        end = displacement_array(moved)
        aim = se2.compose(goal, se2.inverse(se2.relative(car.end(route.ways, x), end)))
        fitted = fit_offsets(route.ways, x, aim, tol, car.model, car.here, 0.0, car.link1)
        if fitted is None or fitted.miss > ROUTE_ACCEPT:
            break  # the route no longer reaches the target by the model
        route = route.with_values(np.array(fitted.offsets), route.delta)
    return route


def _shoot(shooter: _Shooter, car: _Car, route: CycleRoute, plays: int) -> None:
    """Broyden's method from the best play of ``route``'s ways, on its offsets and
    ``delta``, for up to ``plays`` plays or until the steps shrink to nothing."""
    best = shooter.best_of(route.ways)
    if best is None or shooter.within or plays < 2:
        return
    route, r = best
    tol = shooter.tol
    x = route.values
    jac = np.zeros((3, len(x)))
    jac[:, :-1] = car.jacobian(route.ways, x[:-1], tol)
    r_delta, _ = shooter.play(route.with_values(x[:-1], x[-1] + DELTA_STEP))
    jac[:, -1] = (r_delta - r) / DELTA_STEP
    low = np.r_[[-MAX_OFFSET] * (len(x) - 1), DELTA - DELTA_RANGE]
    high = np.r_[[MAX_OFFSET] * (len(x) - 1), DELTA + DELTA_RANGE]
    trust = TRUST
    for _ in range(plays - 1):
        if shooter.within or trust < MIN_TRUST:
            return
        best = shooter.best_of(route.ways)
        assert best is not None
        route, r = best
        x = route.values
        step = -jac.T @ np.linalg.solve(jac @ jac.T + DAMPING * np.eye(3), r)
        if np.abs(step).max() > trust:
            step *= trust / np.abs(step).max()
        new = np.clip(x + step, low, high)
        dx = new - x
        if not dx @ dx > 0:
            return  # against the bounds: nothing left to try
        before = shooter.best_of(route.ways)
        r_new, _ = shooter.play(route.with_values(new[:-1], new[-1]))
        jac += np.outer(r_new - r - jac @ dx, dx) / (dx @ dx)
        if shooter.best_of(route.ways) == before:
            trust *= 0.5


def plan_in_mujoco(
    request: PlanRequest, plays: int = MAX_PLAYS, mu: float | None = None
) -> CyclePlan:
    """A cycle plan for ``request`` that, played open loop in MuJoCo (wheel-floor
    friction ``mu``, default the robot's), ends within the tolerance; Unreachable when
    ``plays`` plays find none."""
    robot = request.robot
    require_serpentine(robot, "the mujoco world")
    goal, phi0, tol = request.checked()
    wave = Wave(robot)
    wave.check()
    car = _Car(
        CycleModel.from_geometry(robot, PRIOR_DISTANCE * body_length(robot)),
        middle(robot, wave.angles_at(0.0, 0.0)),
        link1_from_middle(wave, np.zeros(robot.n_joints)),
    )
    shooter = _Shooter(request, goal, tol, mu)
    start = tuple(float(v) for v in phi0)
    least = 1
    # a route is taught and shot; when that stalls, the next one, of more cycles, is
    # planned by the model the plays so far have taught
    while not shooter.within and shooter.plays < plays:
        found = car.route(goal, tol, least)
        if found is None:
            break
        route = CycleRoute(start, *found, DELTA)
        least = len(route.ways) + 1
        route = _teach(shooter, car, route, min(LEARN_PLAYS, plays - shooter.plays))
        _shoot(shooter, car, route, min(ROUTE_PLAYS, plays - shooter.plays))
    if shooter.best is None or not shooter.within:
        raise _not_converged(shooter)
    _, route, end, _, gait = shooter.best
    plan = CyclePlan(robot, goal, tol, route, gait, end, request.capacity, WORLD, shooter.plays)
    gait.extra.update(plan.summary())
    return plan


def _not_converged(shooter: _Shooter) -> Exception:
    robot, tol = shooter.request.robot, shooter.tol
    if shooter.best is None:
        return out_of_reach(
            f"no serpenoid plan for {robot.name} of up to {HORIZON} cycles reaches the target",
            shooter.request.capacity,
            "choose a nearer target",
            "steer in closed loop (sim goto)",
            params=("target",),
        )
    d, h = pose_error(shooter.best[2], shooter.goal)
    return out_of_reach(
        f"the serpenoid plan for {robot.name} did not converge in MuJoCo: after "
        f"{shooter.plays} plays its nearest table ends {d:.3g} from the target and "
        f"{math.degrees(h):.2f} deg off its heading, outside the tolerance "
        f"({tol.position:.3g}, {math.degrees(tol.heading):.2f} deg)",
        shooter.request.capacity,
        "loosen the tolerance",
        "choose another target",
        "steer in closed loop (sim goto)",
        params=("tolerance", "target"),
    )


def world_check(plan: CyclePlan) -> dict[str, Any]:
    """Where ``plan``'s table ends in the quasi-static world (``quasi_static``), and an
    ``open_loop`` warning when that is outside the tolerance: the plan is made and
    checked for MuJoCo's body and floor."""
    report, warnings = end_check(
        plan,
        plan.gait.predicted,
        "world",
        "in the quasi-static world",
        f"it is made and checked for the {plan.world} world, so played open loop on another "
        "body or floor its end is not to be trusted",
    )
    return {"quasi_static": report, "warnings": warnings}
