"""Closed loop on the emulated robot: play a plan segment by segment, read the body's
pose from the world after each (as a camera or motion capture would), and re-plan the
rest from there.

The host is the bus master (as in ``sim predict``): the servos go to the start
configuration, then each segment (the move to the hub, each loop, the move back) is a
small gait table played by the controller's own player, one SYNC_WRITE per control
tick, while one world samples the servos for the whole run. Before each loop the
remaining displacement (pose now -> target) is split over the loops it still needs
and the loop is fitted again, warm-started from the last one; loops go on until the
move back would end within the tolerance (see ``_follow``)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from snakebot.errors import InputError, quoted
from snakebot.extras import available
from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import sync_write
from snakebot.link.transport import DxlClient
from snakebot.model.gait.common import NEAR_SINGULAR_RCOND
from snakebot.model.gait.common import path as sample_path
from snakebot.model.kinematics import Trajectory
from snakebot.model.plan import se2, serpenoid_goto
from snakebot.model.plan.learn import Response
from snakebot.model.plan.loops import Loop, PlanError, path_motion
from snakebot.model.plan.planner import (
    DEFAULT_HEADING_TOLERANCE,
    DEFAULT_TOLERANCE,
    EndsNearTarget,
    Route,
    Tolerance,
    body_length,
    frame_period_ms,
    guesses,
    loop_counts,
    loop_target,
    motion_dict,
    plan_request,
    pose_dict,
    pose_error,
    routes,
    solve_accuracy,
    solve_loop,
    unreachable,
)
from snakebot.model.robots import Robot
from snakebot.sim.bus.bus import Bus
from snakebot.sim.controller_pty import TABLE_CAPACITY, TICK_MS
from snakebot.sim.physics.select import WORLDS
from snakebot.sim.physics.select import make_world as world_named
from snakebot.workflows.predict import (
    DEFAULT_WORLD_HZ,
    GOAL_POSITION_ADDR,
    come_to_rest,
    move_to_start,
    player_writes,
    sim_url,
)

#: The closed loop runs at most this many times the planned loops.
LOOPS_FACTOR = 5
#: How many times slower than the servos allow a physics world's loops are played:
#: there the trident's body follows the kinematic model to within about 2 % (at full
#: speed its wheels slip 10 % short; measured on MuJoCo).
PHYSICS_SLOWDOWN = 3
MAX_SLOWDOWN = 20
#: Segment kinds that are the closed loop's iterations (each planned from the pose read).
ITERATIONS = ("loop", "cycles")
#: Loops go on until leaving would end within this share of the tolerance (if they
#: run out first, the end is still judged against the whole tolerance), or within the
#: whole tolerance once a loop aimed at the last of the way has been played (see
#: ``_follow``).
STOP_SHARE = 0.5
#: On a physics world loops keep this far from singular configurations (reciprocal
#: condition number of the wheel model) where a route allows: the 3-link snake's loops
#: that came nearer its singular line (0.01 .. 0.017) threw the body a body length in
#: one loop on MuJoCo, those above 0.04 followed the model to 10 %.
PHYSICS_KEEP_OFF = 0.04
#: A loop refitted in closed loop need only be this near its share of the way (relative
#: to the share): the next loop corrects what it misses.
STEP_ACCURACY = 0.2
#: Where no route to the target keeps its loops ``PHYSICS_KEEP_OFF`` from singular
#: configurations, the closed loop goes first to this share of the target pose (of its
#: displacement and of its turn), then from there to the target: other loops. On MuJoCo
#: the 3-link snake's loops stalled short of such a target (seed 31) and the next threw
#: the body a body length (42x the tolerance); by the half-way pose it ended at 0.1x.
WAYPOINT_SHARE = 0.5
#: Bounds of the size factor between one loop and the next one's first guess.
SHRINK_MIN, SHRINK_MAX = 0.2, 1.5
#: The leash: the closed loop gives up once a pose it reads is farther from the target
#: than this many times the start's distance from it, or as many body lengths if that
#: is more (a near target). The farthest the 18 seeded targets of ``bench_goto.py`` went
#: on MuJoCo and still ended within the tolerance: 2.24 body lengths (snake3, seed 35).
LEASH_FACTOR = 3.0


class GotoError(InputError):
    """The closed loop cannot run as asked."""


class Wandered(Exception):
    """A pose read was beyond the leash: the closed loop stops there."""

    def __init__(self, pose: np.ndarray) -> None:
        super().__init__("beyond the leash")
        self.pose = pose


@dataclass(frozen=True)
class Leash:
    """How far from the target the closed loop may go (``LEASH_FACTOR``)."""

    goal: np.ndarray
    reach: float

    @classmethod
    def around(cls, robot: Robot, goal: np.ndarray) -> Leash:
        goal = np.asarray(goal, dtype=float)
        start = pose_error(np.zeros(3), goal)[0]
        return cls(goal, LEASH_FACTOR * max(start, body_length(robot)))

    def distance(self, pose: np.ndarray) -> float:
        return pose_error(pose, self.goal)[0]

    def hold(self, pose: np.ndarray) -> np.ndarray:
        """``pose`` if it is within reach of the target; else stop (``Wandered``)."""
        if self.distance(pose) > self.reach:
            raise Wandered(pose)
        return pose


def make_world(name: str, bus: Bus, robot: Robot, period: float, start: float) -> Any:
    """The world that moves the body, the one ``sim serve`` and ``sim predict`` run
    (:func:`snakebot.sim.physics.select.make_world`): the kinematic minimum-slip model
    (its modelled servos under the body's load), or MuJoCo's physics when this build
    has it."""
    if name not in WORLDS:
        raise GotoError(f"unknown world {quoted(name)}: use {' or '.join(WORLDS)}")
    if name == "mujoco" and not available("mujoco"):
        raise GotoError(
            "the mujoco world needs the physics world (snakebot.sim.physics) and MuJoCo: "
            "pip install 'snakebot[physics]', or use the kinematic world"
        ).about("world")
    return world_named(name, bus, robot, period=period, start=start)


@dataclass
class GotoResult(EndsNearTarget):
    """What the closed loop did: per segment the pose the world reported, the path."""

    robot: Robot
    world: str
    target: np.ndarray
    tolerance: Tolerance
    final: np.ndarray
    segments: list[dict[str, Any]]
    path: Trajectory
    wall_s: float
    stopped: str = "reached"
    why: str = ""

    @property
    def end(self) -> np.ndarray:
        return self.final

    @property
    def iterations(self) -> int:
        """The loops or cycles played, each planned from the pose read."""
        return sum(1 for s in self.segments if s["kind"] in ITERATIONS)

    def summary(self) -> dict[str, Any]:
        return {
            "robot": self.robot.name,
            "world": self.world,
            "target": pose_dict(self.target),
            "final": pose_dict(self.final),
            "error": self.tolerance.report(self.error),
            "iterations": self.iterations,
            "stopped": self.stopped,
            "why": self.why,
            "segments": self.segments,
            "duration_s": float(self.path.t[-1]) if len(self.path.t) else 0.0,
            "wall_s": self.wall_s,
            "path": sample_path(self.path),
        }


class Runner:
    """Plays tables back to back on one bus while one world samples the body."""

    def __init__(
        self,
        client: DxlClient,
        bus: Bus,
        robot: Robot,
        world: Any,
        slowdown: int = 1,
        rest: bool = True,
        leash: Leash | None = None,
    ) -> None:
        self.client, self.bus, self.robot, self.world = client, bus, robot, world
        self.leash = leash
        # wait for the servos to rest after each table: the kinematic world's loaded
        # servos lag its last frame; on MuJoCo the closed loop reads the body as the
        # last frame ends (waiting there sent snake3's seed-35 target from 0.44x the
        # tolerance in 460 loops to 13.4x after 1705, bench_goto.py)
        self.rest = rest
        self.slowdown = slowdown

    def play(self, angles: np.ndarray, period_ms: int) -> np.ndarray:
        """Play joint frames once, each at least ``period_ms`` and no faster than the
        servos' speed allows (slowed down); the body pose the world reports once the
        servos are at rest on the last frame (``rest``), else as it ends. A pose beyond
        the ``leash`` stops the closed loop (``Wandered``)."""
        robot = self.robot
        period_ms = max(period_ms, frame_period_ms(robot, angles) * self.slowdown)
        table = GaitTable(
            robot.servo_ids,
            period_ms,
            False,
            robot.tick_limits,
            robot.angles_to_ticks(angles).astype(np.uint16),
            {},
        )
        tick, blocks = player_writes(table)
        duration = (len(angles) - 1) * period_ms / 1000.0
        start = self.bus.now
        for n, block in enumerate(blocks):
            if block:
                self.bus.run_until(start + min(n * tick, duration))
                self.client.send(sync_write(GOAL_POSITION_ADDR, 4, block))
        # the world sees each write one tick later: let it see the last frame, and the
        # servos come to rest on it (loaded ones lag it)
        end = start + duration + 2 * tick
        period = self.world.period
        self.bus.run_until(end - period)
        before = self.bus.positions(robot.servo_ids)
        self.bus.run_until(end)
        if self.rest:
            come_to_rest(self.bus, robot, period, before)
        pose = np.asarray(self.world.pose, dtype=float)
        return pose if self.leash is None else self.leash.hold(pose)


def goto(
    robot: Robot,
    target: tuple[float, float, float],
    *,
    start: tuple[float, ...] | None = None,
    world: str = "kinematic",
    ideal: bool = False,
    tolerance: float = DEFAULT_TOLERANCE,
    heading_tolerance: float = DEFAULT_HEADING_TOLERANCE,
    world_hz: float = DEFAULT_WORLD_HZ,
    slowdown: int | None = None,
    progress: Any = None,
) -> GotoResult:
    """Take the emulated ``robot`` to ``target`` (relative to its start pose) in closed
    loop, its frames ``slowdown`` times as long as the servos' speed allows (default: 1,
    or PHYSICS_SLOWDOWN on a physics world); ``progress(done, total)`` is called after
    each segment."""
    goal, phi0, tol = plan_request(robot, target, start, tolerance, heading_tolerance)
    waves = uses_serpenoid(robot, world)
    keep_off = NEAR_SINGULAR_RCOND if world == "kinematic" else PHYSICS_KEEP_OFF
    way = None
    if not waves:
        route, kept = _route(robot, phi0, goal, tol, keep_off)
        if kept < keep_off:
            # no route keeps off: go by a waypoint, closed loop to it, then from there
            way = WAYPOINT_SHARE * goal
            way_tol = Tolerance.for_target(robot, way, tolerance, heading_tolerance)
            # (its refits keep off as far as ever, even if this route does not)
            route = _route(robot, phi0, way, way_tol, keep_off)[0]
        else:
            keep_off = kept
    if slowdown is None:
        slowdown = 1 if world == "kinematic" else PHYSICS_SLOWDOWN
    if not (isinstance(slowdown, int) and 1 <= slowdown <= MAX_SLOWDOWN):
        raise PlanError(
            f"the slowdown must be a whole number from 1 to {MAX_SLOWDOWN}, not {slowdown}"
        ).about("slowdown")
    period_ms = 0 if waves else frame_period_ms(robot, route.frames()) * slowdown
    client = DxlClient(sim_url(robot, ideal), echo=False)
    wall0 = time.perf_counter()
    segments: list[dict[str, Any]] = []
    leash = Leash.around(robot, goal)
    wandered = False
    try:
        bus: Bus = client.port.bus
        move_to_start(client, bus, robot, robot.angles_to_ticks(phi0))
        tick = TICK_MS / 1000.0
        w = make_world(world, bus, robot, 1.0 / world_hz, bus.now + tick)
        rest = world != "mujoco"  # see Runner.rest
        try:
            if waves:
                # the wave's frames are timed by its omega, within the servos' speed
                runner = Runner(client, bus, robot, w, 1, rest=rest, leash=leash)
                pose = serpenoid_goto.follow(runner, phi0, goal, tol, segments, progress)
            else:
                runner = Runner(client, bus, robot, w, slowdown, rest=rest, leash=leash)
                pose = np.zeros(3)
                if way is not None:
                    pose = _follow(
                        runner, route, way, way_tol, keep_off, period_ms, segments, progress
                    )
                    # on from wherever the first closed loop ended
                    remaining = se2.relative(pose, goal)
                    route, keep_off = _route(robot, phi0, remaining, tol, keep_off)
                pose = _follow(
                    runner, route, goal, tol, keep_off, period_ms, segments, progress, pose
                )
        except Wandered as exc:
            pose, wandered = exc.pose, True
            segments.append({"kind": "wandered", "frames": 0, "pose": pose_dict(pose)})
        w.stop()
        record = w.record()
    finally:
        client.close()
    path = Trajectory(record.t, record.q)
    result = GotoResult(robot, world, goal, tol, pose, segments, path, time.perf_counter() - wall0)
    result.stopped, result.why = _stop_reason(result, leash, wandered, waves)
    return result


def _stop_reason(result: GotoResult, leash: Leash, wandered: bool, waves: bool) -> tuple[str, str]:
    """Why the closed loop stopped, as a word and a sentence (empty when it reached the
    target)."""
    played = result.iterations
    what = "cycles" if waves else "loops"
    if wandered:
        return "wandered", (
            f"gave up after {played} {what}: a pose read was "
            f"{leash.distance(result.final):.3g} from the target, beyond the leash of "
            f"{leash.reach:.3g} ({LEASH_FACTOR:g} times the start's distance from it, or "
            f"{LEASH_FACTOR:g} body lengths if that is more)"
        )
    if result.within:
        return "reached", ""
    if not waves:
        return "missed", (
            f"ended outside the tolerance after {played} loops (it plays at most "
            f"{LOOPS_FACTOR} times the planned loops)"
        )
    if played < serpenoid_goto.MAX_CYCLES:
        return "near", (
            f"stopped within twice the tolerance after {played} cycles: a fresh plan "
            "costs cycles that each miss by about a tolerance"
        )
    return "limit", f"gave up after {played} cycles, the most it plays"


def uses_serpenoid(robot: Robot, world: str) -> bool:
    """N-link snakes on a physics world steer serpenoid cycles (``serpenoid_goto``):
    there their loops move the body nothing like the minimum-slip model says."""
    return robot.kind == "snake" and robot.n_joints > 2 and world != "kinematic"


def _route(
    robot: Robot, start: np.ndarray, goal: np.ndarray, tol: Tolerance, keep_off: float
) -> tuple[Route, float]:
    """The first route, its loops ``keep_off`` from singular configurations if one
    reaches the goal so, else the planner's; and the distance its loops keep. The
    loops are as many as a table of the emulated controller's capacity holds."""
    for rcond in dict.fromkeys((keep_off, NEAR_SINGULAR_RCOND)):
        for route in routes(robot, start, goal, tol, capacity=TABLE_CAPACITY, keep_off=rcond):
            return route, rcond
    raise unreachable(robot, goal, TABLE_CAPACITY)


def _follow(
    runner: Runner,
    route: Route,
    goal: np.ndarray,
    tol: Tolerance,
    keep_off: float,
    period_ms: int,
    segments: list[dict[str, Any]],
    progress: Any,
    origin: np.ndarray | None = None,
) -> np.ndarray:
    """Play the route in closed loop from the pose ``origin`` (default: the start) to
    ``goal`` (both in the start's frame); returns the pose at the end.

    After the move to the hub, loops go on while leaving now (the move back to the
    start) would end outside ``STOP_SHARE`` of the tolerance, up to ``LOOPS_FACTOR``
    times the planned count. Once a loop aimed at the last of the way (the fewest loops
    a share is split into) has played, and no move back follows whose error the share
    leaves room for, within the whole tolerance is enough: loops that aim at a few
    tolerances are the smallest, and on MuJoCo those can throw the body off by more
    than they correct (the 3-link snake at seed 34 was within 0.7x, looped on for half
    a tolerance and was thrown 0.6 m, 53x, off).

    Before each loop the pose the world reports sets what is left, and the loop is
    fitted again to its share of it: the k-th root with k the nominal loop count for
    what is left (at least 2, so a loop never aims at all of it and a loop that moved
    more or less than the model said is made up for by the next), corrected by what
    the world made of the loops so far (``learn.Response``)."""
    robot = runner.robot
    scale = body_length(robot)
    loop = route.loop
    leave = route.leave
    back = path_motion(robot, leave) if len(leave) > 1 else np.zeros(3)
    most = LOOPS_FACTOR * route.count
    total = most + 2
    pose = np.zeros(3) if origin is None else origin
    done = 0
    response = Response(scale)

    def play(kind: str, angles: np.ndarray, planned: np.ndarray | None = None) -> None:
        nonlocal pose, done
        before = pose
        pose = runner.play(angles, period_ms)
        moved = se2.relative(before, pose)
        segments.append({"kind": kind, "frames": len(angles) - 1, "pose": pose_dict(pose)})
        segments[-1]["motion"] = motion_dict(moved)
        if planned is not None:
            segments[-1]["planned"] = motion_dict(planned)
            response.add(planned, moved)
        done += 1
        if progress is not None:
            progress(done, total)

    if len(route.enter) > 1:
        play("to hub", route.enter)
    # the fewest loops a share of the way is split into: a loop at that count aims at
    # the last of it (without a move back, whose own error the share leaves room for)
    least = loop_counts(robot, np.zeros(3), most)[0] if len(leave) <= 1 else None
    count = None
    for _ in range(most):
        d, h = pose_error(se2.compose(pose, back), goal)
        share = 1.0 if count is not None and count == least else STOP_SHARE
        if d <= share * tol.position and abs(h) <= share * tol.heading:
            break
        remaining = se2.relative(pose, goal)
        count = loop_counts(robot, remaining, most)[0]
        wanted = response.command(
            loop_target(robot, route.start, loop.hub, remaining, count, entered=True)
        )
        accuracy = max(
            solve_accuracy(robot, tol),
            STEP_ACCURACY * float(np.linalg.norm(wanted * response.weights)),
        )
        for tries in (
            [shrunk(loop, wanted, response.weights), loop.coefficients],
            guesses(robot, None),
        ):
            refit = solve_loop(robot, loop.hub, wanted, scale, tries, accuracy, keep_off)
            if refit is not None:
                loop = refit
                break
        # a failed fit keeps the last loop: the next one corrects
        play("loop", loop.angles(), loop.motion)
    if len(leave) > 1:
        play("to start", leave)
    return pose


def shrunk(loop: Loop, wanted: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The loop's coefficients scaled to the size a loop moving the body by ``wanted``
    has: a loop's motion grows with its area, the square of its size. A loop fitted
    from the last one unscaled keeps its size and moves the body a little by large
    motions that nearly cancel, which a slipping world does not reproduce. ``weights``
    make a motion's position and heading comparable."""
    have = float(np.linalg.norm(loop.motion * weights))
    want = float(np.linalg.norm(wanted * weights))
    factor = 1.0 if have <= 0 else float(np.clip(np.sqrt(want / have), SHRINK_MIN, SHRINK_MAX))
    return loop.coefficients * factor
