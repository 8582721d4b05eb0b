"""Plans that take the robot to a target pose: a gait table the controller plays.

The method (for the trident, the 3-link snake and N-link snakes alike): the joints go
from the start configuration to a hub (a straight joint move), run one closed joint loop
k times, and come back to the start. A loop through the hub moves the body by a fixed
pose D wherever it is (``loops``), so the whole plan moves it by T_in D^k T_out, and the
target is met by solving D = (T_in^-1 target T_out^-1)^(1/k): the k-th root along the
target's screw motion, which turns the rest of the way at the same rate. The root is
small for large k, so the loop is small and the solve well conditioned; it is a
least-squares fit of the loop's coefficients with the exact motion from the C core, the
fields being re-evaluated all along the way by the integration, where the brackets give
only the leading order. The solver starts from several deterministic guesses (for a
snake, a serpenoid wave among them). Routes are tried from the fewest loops up
(``candidates``): the nominal count for the distance and turn at every hub, then twice
as many at every hub, and so on up to what a table of the capacity planned for holds;
a route of few loops is found first where one exists, and it is the shorter plan.

The table is then written in ticks loop by loop, re-planned on the way as the thesis
re-evaluates its fields: before each loop, what is left (from the pose the loops so
far reach as played) is split over the loops to come, and the loop, rounded to ticks,
is nudged tick by tick (refitted first if that is not enough) to its share, so the
rounding does not compound over the loops. The table is timed to the servos' speed
(frame period a whole number of controller ticks), checked against the joint limits,
and its motion as played (``gait.common.table_motion``) must end at the target within
the tolerance; else the next route is tried. A target that no hub and no k reaches
within the table's capacity (unless told, the robot's board's, the CM-530's:
``DEFAULT_CAPACITY``) raises ``Unreachable``."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snakebot.facts.boards import ROBOT_BOARD, TABLE_CAPACITY, largest_board
from snakebot.formats.gaittable import MAX_TABLE_BYTES, max_frames, table_size
from snakebot.model.gait.common import (
    NEAR_SINGULAR_RCOND,
    Gait,
    motion,
    motion_frame,
    path,
    singularity_warnings,
    table_motion,
)
from snakebot.model.gait.field import SPEED_MARGIN
from snakebot.model.gait.limits import check_ticks
from snakebot.model.kinematics import KinematicsError, Trajectory
from snakebot.model.plan import se2
from snakebot.model.plan.loops import (
    FRAMES,
    HARMONICS,
    Loop,
    PlanError,
    limits,
    path_motion,
    refine_ticks,
    solve_loop,
)
from snakebot.model.player import TICK_MS
from snakebot.model.robots import TICKS_PER_RAD, Robot

#: Default tolerance: a fraction of the distance to the target, and a heading (rad).
DEFAULT_TOLERANCE = 0.02
DEFAULT_HEADING_TOLERANCE = math.radians(2.0)
#: The position tolerance never drops below this fraction of a body length times the
#: relative tolerance (a pure turn still has one).
MIN_DISTANCE_BODIES = 0.1
#: Nominal motion per loop, in body lengths and radians: sets the first loop count tried.
STEP_BODIES = 0.08
STEP_TURN = 0.25
#: Largest joint step per frame (rad) on the moves between start and hub.
TRANSITION_STEP = 0.08
#: Share of the tolerance a refined loop's error may use, divided among the loops.
REFINE_SHARE = 0.3
#: Refits of a loop (a fresh least-squares fit when nudging its ticks is not enough)
#: that may fail in one table before its other loops are only nudged: each failed
#: refit costs as much as nudging dozens of loops, and in a route whose refits keep
#: failing they rarely save the plan.
REFIT_FAILURES = 3

DEFAULT_BOARD = ROBOT_BOARD
DEFAULT_CAPACITY = TABLE_CAPACITY[DEFAULT_BOARD]
"""The table capacity (bytes) a plan is made for unless told (by the controller it is
for, or a board or a number): the robot's board's, the CM-530's."""


class Unreachable(PlanError):
    """No plan inside the limits reaches the target (exit status 1, nothing written)."""


def body_length(robot: Robot) -> float:
    """One body length in the robot's units: a snake's links end to end, a trident's
    span from wheel to wheel through the base (arms stretched)."""
    if robot.kind == "snake":
        return 2.0 * robot.l * robot.links
    return 2.0 * (robot.r + robot.l)


def default_start(robot: Robot) -> np.ndarray:
    """The 3-link snake at the thesis's pi/3, -pi/3 (clear of its singular line
    phi1 = phi2); every other robot straight / with its arms radial."""
    if robot.kind == "snake" and robot.n_joints == 2:
        return np.array([math.pi / 3, -math.pi / 3])
    return np.zeros(robot.n_joints)


#: The 3-link snake's hubs (phi1 > phi2 side), best first: from (0.5, -1.4) small loops
#: move it along all six signed directions of x, y, theta (a survey at 0.05 body
#: lengths and 0.08 rad per loop); the others each reach some of them.
SNAKE3_HUBS = ((0.5, -1.4), (1.4, -0.5), (-0.3, -1.3), (1.3, 0.3), (math.pi / 3, -math.pi / 3))


def hubs(robot: Robot, start: np.ndarray) -> list[np.ndarray]:
    """Hub configurations to try, the start first (no moves to and from a hub). The
    3-link snake's loops stay on the start's side of its singular line phi1 = phi2."""
    out = [start]
    if robot.kind == "snake" and robot.n_joints == 2:
        side = 1.0 if start[0] >= start[1] else -1.0
        out += [side * np.array(h) for h in SNAKE3_HUBS]
    elif robot.kind == "trident":
        out += [np.full(robot.n_joints, 0.3), np.full(robot.n_joints, -0.3)]
    lo, hi = limits(robot)
    unique: list[np.ndarray] = []
    for h in out:
        if np.all((h >= lo) & (h <= hi)) and not any(np.allclose(h, u) for u in unique):
            unique.append(h)
    return unique


def guesses(robot: Robot, previous: np.ndarray | None) -> list[np.ndarray]:
    """Starting coefficients for the solver: the last solution, for a snake a serpenoid
    wave (joint k at phase k pi / 2), then deterministic random loops."""
    n = robot.n_joints * 2 * HARMONICS
    out = [] if previous is None else [previous]
    if robot.kind == "snake" and robot.n_joints > 2:
        wave = np.zeros((robot.n_joints, 2 * HARMONICS))
        for j in range(robot.n_joints):
            wave[j, 0] = 0.5 * math.cos(j * math.pi / 2)
            wave[j, 1] = -0.5 * math.sin(j * math.pi / 2)
        out.append(wave.ravel())
    out += [np.random.default_rng(seed).normal(0.0, 0.3, n) for seed in range(4)]
    return out


def same_joints(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two joint configurations (finite) are one, by ``np.allclose``'s test
    (|a - b| <= 1e-8 + 1e-5 |b| each): on a few numbers a twentieth of its cost, and the
    program planner's fit asks it for every straight move of every route it tries."""
    return all(
        abs(x - y) <= 1e-8 + 1e-5 * abs(y) for x, y in zip(a.tolist(), b.tolist(), strict=True)
    )


def ramp(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Frames of a straight joint move from a to b (both included)."""
    if same_joints(a, b):
        return a[None, :]
    steps = max(1, math.ceil(float(np.abs(b - a).max()) / TRANSITION_STEP - 1e-9))
    return a + (b - a) * (np.arange(steps + 1) / steps)[:, None]


@dataclass(frozen=True)
class Tolerance:
    """How near the end pose must be: ``position`` (length units) and ``heading`` (rad)."""

    position: float
    heading: float

    @classmethod
    def for_target(
        cls, robot: Robot, target: np.ndarray, relative: float, heading: float
    ) -> Tolerance:
        if not 0 < relative < 1:
            raise PlanError(
                f"the tolerance is a fraction of the distance (0..1), not {relative}"
            ).about("tolerance")
        if not heading > 0:
            raise PlanError(f"the heading tolerance must be positive, not {heading}").about(
                "heading_tolerance"
            )
        reach = max(float(np.hypot(*target[:2])), MIN_DISTANCE_BODIES * body_length(robot))
        return cls(relative * reach, heading)

    def admits(self, error: tuple[float, float]) -> bool:
        """Whether a pose error (distance, heading difference) is within both bounds."""
        d, h = error
        return d <= self.position and abs(h) <= self.heading

    def report(self, error: tuple[float, float]) -> dict[str, Any]:
        """A pose error beside these bounds, as the JSON reports of plan and goto give it."""
        d, h = error
        return {
            "position": d,
            "heading_rad": h,
            "position_tolerance": self.position,
            "heading_tolerance_rad": self.heading,
            "within": self.admits(error),
        }


def pose_error(reached: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    """Distance between the reference points, and the heading difference wrapped to
    (-pi, pi]."""
    d = float(np.hypot(*(reached[:2] - target[:2])))
    h = (reached[2] - target[2] + math.pi) % (2 * math.pi) - math.pi
    return d, float(h)


@dataclass
class Route:
    """The joint path of a plan: start -> hub, k loops, hub -> start."""

    robot: Robot
    start: np.ndarray
    loop: Loop
    count: int

    @property
    def enter(self) -> np.ndarray:
        return ramp(self.start, self.loop.hub)

    @property
    def leave(self) -> np.ndarray:
        return ramp(self.loop.hub, self.start)

    def pieces(self) -> list[tuple[str, np.ndarray]]:
        """(kind, frames) of each segment, each starting where the last ended."""
        out = []
        if len(self.enter) > 1:
            out.append(("to hub", self.enter))
        out += [("loop", self.loop.angles())] * self.count
        if len(self.leave) > 1:
            out.append(("to start", self.leave))
        return out

    def frames(self) -> np.ndarray:
        rows = [self.start[None, :]]
        for _, piece in self.pieces():
            rows.append(piece[1:])
        return np.vstack(rows)


def frame_period_ms(robot: Robot, angles: np.ndarray) -> int:
    """The shortest frame period (whole controller ticks) at which no joint's step
    between frames exceeds the servo's speed times the margin."""
    step = float(np.abs(np.diff(angles, axis=0)).max()) if len(angles) > 1 else 0.0
    # one tick of rounding on each end adds at most two ticks' angle to a step
    step += 2.0 / TICKS_PER_RAD
    seconds = step / (SPEED_MARGIN * robot.max_speed_rad_s)
    return max(1, math.ceil(seconds * 1000.0 / TICK_MS - 1e-9)) * TICK_MS


class EndsNearTarget:
    """The error and verdict of something that ends at a pose (``end``, by default its
    ``reached`` attribute) aiming at ``target`` within ``tolerance``."""

    target: np.ndarray
    tolerance: Tolerance

    @property
    def end(self) -> np.ndarray:
        return self.reached  # type: ignore[attr-defined, no-any-return]

    @property
    def error(self) -> tuple[float, float]:
        return pose_error(self.end, self.target)

    @property
    def within(self) -> bool:
        return self.tolerance.admits(self.error)


@dataclass
class Plan(EndsNearTarget):
    """A plan and what is known about it; ``gait`` is the table to write."""

    robot: Robot
    target: np.ndarray
    tolerance: Tolerance
    route: Route
    gait: Gait
    reached: np.ndarray
    capacity: int
    """The table capacity (bytes) the plan was made for; its table fits it."""
    segments: list[dict[str, Any]] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        return {
            "robot": self.robot.name,
            "frame": motion_frame(self.robot),
            "target": pose_dict(self.target),
            "predicted_final": pose_dict(self.reached),
            "error": self.tolerance.report(self.error),
            "start_rad": self.route.start.tolist(),
            "hub_rad": self.route.loop.hub.tolist(),
            "loops": self.route.count,
            "segments": self.segments,
            "frames": len(self.gait.ticks),
            "table_bytes": table_size(self.robot.n_joints, len(self.gait.ticks)),
            "capacity_bytes": self.capacity,
            "frame_period_ms": self.gait.period_ms,
            "duration_s": round(self.gait.duration_s, 6),
            "warnings": self.gait.warnings,
        }


def pose_dict(q: np.ndarray) -> dict[str, float]:
    return {"x": float(q[0]), "y": float(q[1]), "theta": float(q[2])}


def motion_dict(moved: np.ndarray) -> dict[str, float]:
    """A body displacement (x, y, theta) as the reports give it."""
    return {"dx": float(moved[0]), "dy": float(moved[1]), "dtheta": float(moved[2])}


def _segments(robot: Robot, route: Route, ticks: np.ndarray, period_s: float) -> list[dict]:
    """Each segment's frames and its motion as played from the rounded ticks."""
    out, first = [], 0
    angles = robot.ticks_to_angles(ticks)
    for kind, piece in route.pieces():
        last = first + len(piece) - 1
        moved = path_motion(robot, angles[first : last + 1])
        out.append(
            {
                "kind": kind,
                "first_frame": first,
                "frames": len(piece) - 1,
                "duration_s": round((len(piece) - 1) * period_s, 6),
                "motion": motion_dict(moved),
            }
        )
        first = last
    return out


def loop_target(
    robot: Robot,
    start: np.ndarray,
    hub: np.ndarray,
    target: np.ndarray,
    k: int,
    *,
    entered: bool = False,
) -> np.ndarray:
    """What each of k loops through ``hub`` must move the body by so that (the move from
    ``start`` to the hub unless already ``entered``,) the loops and the move back to
    ``start`` end at ``target``."""
    moves = not same_joints(start, hub)
    enter = path_motion(robot, ramp(start, hub)) if moves and not entered else np.zeros(3)
    leave = path_motion(robot, ramp(hub, start)) if moves else np.zeros(3)
    middle = se2.compose(se2.compose(se2.inverse(enter), target), se2.inverse(leave))
    middle[2] = (middle[2] + math.pi) % (2 * math.pi) - math.pi
    return se2.root(middle, k)


def solve_accuracy(robot: Robot, tol: Tolerance) -> float:
    """The scaled residual a loop fit must reach: a tenth of the tolerance."""
    return 0.1 * min(tol.position / body_length(robot), tol.heading)


def loop_counts(robot: Robot, target: np.ndarray, most: int) -> list[int]:
    """Loop counts to try: a nominal count for the distance and turn, then the most."""
    bodies = float(np.hypot(*target[:2])) / body_length(robot)
    nominal = math.ceil(max(bodies / STEP_BODIES, abs(target[2]) / STEP_TURN, 2.0))
    out = [min(nominal, most)]
    if most not in out:
        out.append(most)
    return [k for k in out if k >= 1]


def plan_request(
    robot: Robot,
    target: tuple[float, float, float],
    start: tuple[float, ...] | None,
    tolerance: float,
    heading_tolerance: float,
) -> tuple[np.ndarray, np.ndarray, Tolerance]:
    """What every planner starts from, checked: the target pose, the start joints
    (default_start unless given) and the tolerance for that target; PlanError if the
    target is not three finite numbers or the start is not one the robot can plan from."""
    goal = np.asarray(target, dtype=float)
    if goal.shape != (3,) or not np.all(np.isfinite(goal)):
        raise PlanError("the target pose needs three finite numbers X,Y,THETA").about("target")
    phi0 = default_start(robot) if start is None else np.asarray(start, dtype=float)
    validate_start(robot, phi0)
    return goal, phi0, Tolerance.for_target(robot, goal, tolerance, heading_tolerance)


def validate_start(robot: Robot, start: np.ndarray) -> None:
    """PlanError unless ``robot`` has a wheel model and ``start`` is inside its limits."""
    if robot.kind not in ("snake", "trident"):
        raise PlanError(
            f"{robot.name} is a {robot.kind}, which has a field model only (no wheel-by-wheel "
            "model to plan with): plan for a snake or a trident (snake3, snake5, trident)"
        )
    lo = np.array([j.min_rad for j in robot.joints])
    hi = np.array([j.max_rad for j in robot.joints])
    if len(start) != robot.n_joints:
        raise PlanError(f"the start needs {robot.n_joints} joint angles for {robot.name}").about(
            "start"
        )
    bad = np.flatnonzero((start < lo) | (start > hi))
    if bad.size:
        j = robot.joints[int(bad[0])]
        raise PlanError(
            f"the start puts joint {j.name} at {math.degrees(start[bad[0]]):.1f} deg, outside "
            f"its limits {math.degrees(j.min_rad):.1f}..{math.degrees(j.max_rad):.1f} deg"
        ).about("start")


def growing_counts(robot: Robot, target: np.ndarray, most: int) -> list[int]:
    """Loop counts from the fewest up: the nominal count, doubled while below the most a
    table holds, then the most."""
    counts = loop_counts(robot, target, most)
    if not counts:
        return []
    out, k = [], counts[0]
    while k < most:
        out.append(k)
        k *= 2
    return [*out, most]


def most_loops(robot: Robot, start: np.ndarray, hub: np.ndarray, capacity: int) -> int:
    """The most loops through ``hub`` a table of ``capacity`` bytes holds beside the moves
    from ``start`` to the hub and back."""
    transition = len(ramp(start, hub)) - 1
    return (max_frames(robot.n_joints, capacity) - 1 - 2 * transition) // FRAMES


def candidates(
    robot: Robot,
    start: np.ndarray,
    target: np.ndarray,
    capacity: int,
    *,
    count: int | None = None,
    hub: np.ndarray | None = None,
    growing: bool = False,
) -> Iterator[tuple[int, np.ndarray, int]]:
    """(hub index, hub, loop count) to try, within what a table of ``capacity`` bytes
    holds. By default hub by hub, each at its nominal count and then the most (the first
    route that exists, whatever its size: the closed loop's choice). ``growing``: the
    fewest loops first, a count at every hub before twice as many (``growing_counts``):
    a route of few loops is quick to fit and to write, one of many loops is slow to
    write (each loop nudged to its share), so the plan tries those last."""
    chosen = [hub] if hub is not None else hubs(robot, start)
    lists = []
    for h in chosen:
        most = most_loops(robot, start, h, capacity)
        if count is not None:
            lists.append([count] if 1 <= count <= most else [])
        else:
            lists.append((growing_counts if growing else loop_counts)(robot, target, most))
    if growing:
        order = [(r, i) for r in range(max(map(len, lists), default=0)) for i in range(len(lists))]
    else:
        order = [(r, i) for i, counts in enumerate(lists) for r in range(len(counts))]
    for r, i in order:
        if r < len(lists[i]):
            yield i, chosen[i], lists[i][r]


def routes(
    robot: Robot,
    start: np.ndarray,
    target: np.ndarray,
    tol: Tolerance,
    *,
    capacity: int,
    count: int | None = None,
    hub: np.ndarray | None = None,
    previous: np.ndarray | None = None,
    keep_off: float = NEAR_SINGULAR_RCOND,
    growing: bool = False,
) -> Iterator[Route]:
    """Routes (hub, loop, count) whose joint path as planned reaches ``target``, in the
    order of ``candidates``, each inside a table of ``capacity`` bytes; the loops keep
    off configurations whose reciprocal condition number is below ``keep_off``.

    ``growing``: a hub's fit at one count starts first from the loop that came nearest
    at its last count, shrunk for the shorter way (a loop's motion grows with its area,
    the square of its size); where the last count's loop could not reach its share
    (too large a loop for the joints' range, or nearing a singular configuration), the
    smaller one often can: of 30 seeded 3-link snake targets two failed at their first
    counts, and from the generic guesses alone needed 48 and 24 loops (more than a 2 KB
    table holds), from the nearest loop 12 and 20."""
    scale = body_length(robot)
    accuracy = solve_accuracy(robot, tol)
    dead: set[int] = set()
    nearest: dict[int, tuple[int, np.ndarray]] = {}  # hub index: (count, coefficients)
    for i, h, k in candidates(
        robot, start, target, capacity, count=count, hub=hub, growing=growing
    ):
        if i in dead:
            continue
        try:
            wanted = loop_target(robot, start, h, target, k)
        except KinematicsError:
            dead.add(i)  # the moves to or from this hub cross a singular configuration
            continue
        starts = guesses(robot, previous)
        if growing and i in nearest:
            before, coefficients = nearest[i]
            starts.insert(0, coefficients * math.sqrt(before / k))

        def remember(coefficients: np.ndarray, i: int = i, k: int = k) -> None:
            nearest[i] = (k, coefficients)

        loop = solve_loop(robot, h, wanted, scale, starts, accuracy, keep_off, remember)
        if loop is not None:
            yield Route(robot, start, loop, k)


def check_capacity(robot: Robot, capacity: int) -> None:
    """PlanError unless a table of ``capacity`` bytes is one a controller may take and
    holds at least one loop of ``robot``'s joints."""
    least = table_size(robot.n_joints, FRAMES + 1)
    if not least <= capacity <= MAX_TABLE_BYTES:
        raise PlanError(
            f"a capacity of {capacity} bytes is outside what a plan for {robot.name} can use: "
            f"from {least} (one loop of {FRAMES} frames of {robot.n_joints} joints) to "
            f"{MAX_TABLE_BYTES} (the largest table a controller takes); give a number in "
            f"that range or a board ({', '.join(sorted(TABLE_CAPACITY))})"
        ).about("capacity")


def capacity_words(capacity: int) -> str:
    """The capacity planned for, naming the board it is when it is one's."""
    boards = [name for name, size in TABLE_CAPACITY.items() if size == capacity]
    return f"a table of {capacity} bytes" + (f" (the {'/'.join(boards)} board's)" if boards else "")


def out_of_reach(text: str, capacity: int, *ways: str, params: tuple[str, ...] = ()) -> Unreachable:
    """Unreachable: ``text``, then the ways out: ``ways`` (which change the parameters
    ``params``) and, when a board holds more than ``capacity``, a plan for a larger table."""
    out = list(ways)
    largest = largest_board()
    if capacity < TABLE_CAPACITY[largest]:
        out.append(
            f"plan for a larger table (the {largest}'s {TABLE_CAPACITY[largest]} bytes, or "
            "the capacity the controller reports)"
        )
        params = (*params, "capacity")
    said = out[0] if len(out) == 1 else ", ".join(out[:-1]) + " or " + out[-1]
    return Unreachable(f"{text}: {said}; no file was written").about(*params)


def unreachable(robot: Robot, target: np.ndarray, capacity: int) -> Unreachable:
    return out_of_reach(
        f"no plan for {robot.name} reaches x = {target[0]:.4g}, y = {target[1]:.4g}, "
        f"theta = {math.degrees(target[2]):.1f} deg inside its joint limits and servo speed "
        f"within {capacity_words(capacity)}",
        capacity,
        "choose a nearer target",
        "go in steps with several plans",
        params=("target",),
    )


@dataclass(frozen=True)
class PlanRequest:
    """A plan asked for: ``robot`` from rest at ``start`` (joint angles; the robot's
    default start if None) to ``target`` (x, y, theta relative to the start pose),
    ending within ``tolerance`` (a fraction of the distance) and ``heading_tolerance``
    (rad), in at most ``capacity`` bytes. The table planner and the program planner take
    the same request."""

    robot: Robot
    target: tuple[float, float, float]
    start: tuple[float, ...] | None = None
    tolerance: float = DEFAULT_TOLERANCE
    heading_tolerance: float = DEFAULT_HEADING_TOLERANCE
    capacity: int = DEFAULT_CAPACITY

    def checked(self) -> tuple[np.ndarray, np.ndarray, Tolerance]:
        """The target pose, the start joints and the tolerance (:func:`plan_request`),
        the capacity checked too (:func:`check_capacity`)."""
        robot = self.robot
        checked = plan_request(
            robot, self.target, self.start, self.tolerance, self.heading_tolerance
        )
        check_capacity(robot, self.capacity)
        return checked


def make_plan(request: PlanRequest) -> Plan:
    """A gait table taking the robot where ``request`` asks, in a table of at most its
    capacity; raises Unreachable if none fits."""
    robot, capacity = request.robot, request.capacity
    goal, phi0, tol = request.checked()
    best: Plan | None = None
    for route in routes(robot, phi0, goal, tol, capacity=capacity, growing=True):
        plan = _table_plan(robot, goal, tol, phi0, route, capacity)
        if best is None or plan.error[0] / tol.position < best.error[0] / tol.position:
            best = plan
        if plan.within:
            break
    if best is None:
        raise unreachable(robot, goal, capacity)
    plan = best
    gait = plan.gait
    if not plan.within:
        d, h = plan.error
        raise out_of_reach(
            f"the best plan for {robot.name} in {capacity_words(capacity)} ends {d:.3g} "
            f"from the target and {math.degrees(h):.2f} deg off its heading, outside the "
            f"tolerance ({tol.position:.3g}, {math.degrees(tol.heading):.2f} deg)",
            capacity,
            "loosen the tolerance",
            "choose another target",
            params=("tolerance", "target"),
        )
    gait.extra.update(plan.summary())
    return plan


def _table_plan(
    robot: Robot,
    goal: np.ndarray,
    tol: Tolerance,
    phi0: np.ndarray,
    route: Route,
    capacity: int,
) -> Plan:
    """The route as a table, re-planned loop by loop on the ticks as played: the moves to
    and from the hub rounded, then each loop rounded and refined tick by tick
    (``refine_ticks``) to its share of what is left of the way (the k-th root, as at the
    start), so each loop corrects what rounding did to the ones before (refitted when
    that is not enough, until ``REFIT_FAILURES`` refits have failed); timed, and its
    motion as played checked."""
    enter = robot.angles_to_ticks(route.enter)
    leave = robot.angles_to_ticks(route.leave)
    back = se2.inverse(_ticks_motion(robot, leave))
    scale = body_length(robot)
    accuracy = REFINE_SHARE * min(tol.position / scale, tol.heading)
    pose = _ticks_motion(robot, enter)
    loop = robot.angles_to_ticks(route.loop.angles())
    coefficients = route.loop.coefficients
    rows = [enter]
    failed = 0
    for i in range(route.count):
        wanted = se2.root(se2.compose(se2.relative(pose, goal), back), route.count - i)
        loop, err = refine_ticks(robot, loop, wanted, scale, accuracy)
        if err > accuracy and failed < REFIT_FAILURES:
            # too far for a few ticks: fit the loop again, then round
            fit = solve_loop(robot, route.loop.hub, wanted, scale, [coefficients], accuracy)
            failed += fit is None
            if fit is not None:
                again, err_again = refine_ticks(
                    robot, robot.angles_to_ticks(fit.angles()), wanted, scale, accuracy
                )
                if err_again < err:
                    loop, coefficients = again, fit.coefficients
        pose = se2.compose(pose, _ticks_motion(robot, loop))
        rows.append(loop[1:])
    rows.append(leave[1:])
    ticks = np.vstack(rows)
    period_ms = frame_period_ms(robot, robot.ticks_to_angles(ticks))
    dt = period_ms / 1000.0
    check_ticks(robot, ticks, dt, False)
    played = table_motion(robot, robot.ticks_to_angles(ticks), dt, False, per_interval=2)
    reached = played.trajectory.q[-1, :3]
    gait = _gait(robot, route, ticks, period_ms, played.trajectory, played.note())
    segments = _segments(robot, route, ticks, dt)
    return Plan(robot, goal, tol, route, gait, reached, capacity, segments)


def _ticks_motion(robot: Robot, ticks: np.ndarray) -> np.ndarray:
    """Body motion over frames given in ticks (none for a single frame)."""
    return path_motion(robot, robot.ticks_to_angles(ticks)) if len(ticks) > 1 else np.zeros(3)


def _gait(
    robot: Robot,
    route: Route,
    ticks: np.ndarray,
    period_ms: int,
    table_traj: Trajectory,
    note: dict[str, Any],
) -> Gait:
    moved = motion(table_traj)
    return Gait(
        robot,
        "plan",
        {
            "hub_rad": route.loop.hub.tolist(),
            "loops": route.count,
            "loop_frames": FRAMES,
            "harmonics": HARMONICS,
            "loop_coefficients": route.loop.coefficients.tolist(),
            "rate_hz": 1000.0 / period_ms,
        },
        period_ms,
        False,
        ticks,
        moved,
        {**moved, **note},
        path(table_traj),
        path(table_traj),
        warnings=singularity_warnings({"plan as written": table_traj}),
    )
