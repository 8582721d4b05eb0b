"""Benchmark: the physics world against raw MuJoCo on the same model, and the physics
search against a batched ``mujoco.rollout`` of the same runs.

Every figure is emulated seconds per CPU second of this process (the machine is shared:
CPU time counts what other processes take less), the median of rounds that alternate
between the ways, so load hits each alike. On snake5's MJCF at the physics world's own
time step (``PhysicsWorld.model``, the very model it steps):

* raw MuJoCo: the same model with MuJoCo-native position actuators (force = kp (ctrl -
  q) within the stall torque) told the same serpenoid, from the same start, the same
  number of steps: ``mujoco.rollout`` of one trajectory, and a Python loop over
  ``mj_step`` (the motion matters: a driven body takes the contact solver more
  iterations than one at rest);
* the physics world alone: ``PhysicsWorld`` on the emulated bus, the servos told new
  goals (a serpenoid) every 20 ms by SYNC_WRITEs on the bus, as a player would, with no
  client between: the world's per-tick bookkeeping (each servo's registers to a drive,
  the physics back to each servo, the samples) and the bus's;
* a whole play, as `snakebot sim predict --world mujoco` runs it (player, client, bus):
  for scale.

Goal: the physics world at least :data:`GOAL_WORLD` of raw MuJoCo's speed (the
rollout). Then the search: ``gait search --world mujoco``'s evaluations per CPU second
(one core, in process) against a batched ``mujoco.rollout`` of the same runs (the very
tables the search plays, each frame held for its period; one thread, so per core), goal
:data:`GOAL_SEARCH` of it. The search's runs also move the robot to their first frame,
which the rollout's do not: that time counts against the search.

    .venv/bin/python bench/bench_physics_raw.py [--quick]
"""

from __future__ import annotations

import copy
import math
import os
import statistics
import sys
import time
from collections.abc import Callable

import mujoco
import numpy as np
from mujoco import rollout

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.formats.protocol import sync_write
from snakebot.model.gait import serpenoid
from snakebot.model.robots import TICKS_PER_RAD, load_robot
from snakebot.sim.options import SimOptions
from snakebot.sim.physics.world import PhysicsWorld

GOAL_WORLD = 0.5
GOAL_SEARCH = 0.6
GOAL_AND_SPEED = 30  # Goal Position, then Moving Speed
FRAME_S = 0.02
SECONDS = 4.0
SEARCH_RUNS = 8
SEARCH_CYCLES = 3


def goals_at(robot, t: float) -> bytes:  # noqa: ANN001
    """A SYNC_WRITE of every servo's goal on a serpenoid at ``t``, moving speed 0 (full)."""
    phi = 0.5 * np.sin(2 * math.pi * t + np.arange(robot.n_joints) * math.pi / 2)
    ticks = robot.angles_to_ticks(phi)
    block = {
        sid: int(g).to_bytes(2, "little") + (0).to_bytes(2, "little")
        for sid, g in zip(robot.servo_ids, ticks, strict=True)
    }
    return sync_write(GOAL_AND_SPEED, 4, block)


def world_alone(robot, seconds: float) -> tuple[float, PhysicsWorld]:  # noqa: ANN001
    """Emulated seconds per CPU second of the physics world driven over the bus."""
    bus = SimOptions(robot="snake5").build_bus()
    world = PhysicsWorld(bus, robot)
    frames = [goals_at(robot, k * FRAME_S) for k in range(round(seconds / FRAME_S))]
    cpu = time.process_time()
    for k, packet in enumerate(frames):
        bus.run_until(k * FRAME_S)
        bus.master_write(packet)
    bus.run_until(seconds)
    spent = time.process_time() - cpu
    world.stop()
    return seconds / spent, world


def raw_model(robot) -> tuple[mujoco.MjModel, np.ndarray, float]:  # noqa: ANN001
    """The world's model made a plain position-servo model, MuJoCo-native: each actuator
    force = kp (ctrl - q) within the stall torque, kp the AX-12's full drive over its
    default compliance slope (32 ticks); the state at the world's start; its time step."""
    world = PhysicsWorld(SimOptions(robot="snake5").build_bus(), robot)
    world.stop()
    model = copy.deepcopy(world.model)
    stall = world.actuator.stall_nm
    kp = stall * TICKS_PER_RAD / 32.0
    model.actuator_gainprm[:, 0] = kp
    model.actuator_biasprm[:, :3] = [0.0, -kp, 0.0]
    model.actuator_forcerange[:] = [-stall, stall]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, world.data, state, spec)
    return model, state, model.opt.timestep


def serpenoid_controls(robot, model: mujoco.MjModel, seconds: float) -> np.ndarray:  # noqa: ANN001
    """Each step's joint targets: the serpenoid the world's servos are told, held for
    each 20 ms frame."""
    dt = model.opt.timestep
    steps = round(seconds / dt)
    frames = np.floor(np.arange(steps) * dt / FRAME_S) * FRAME_S
    phase = 2 * math.pi * frames[:, None] + np.arange(robot.n_joints) * math.pi / 2
    return 0.5 * np.sin(phase)


def table_controls(model: mujoco.MjModel, angles: np.ndarray, period_s: float, seconds: float):  # noqa: ANN201
    """Each step's joint targets from a table: its frames' joint angles, each held for
    its frame period, the last to the end (as the controller plays it)."""
    steps = round(seconds / model.opt.timestep)
    frame = np.floor(np.arange(steps) * model.opt.timestep / period_s + 1e-9).astype(int)
    return angles[np.minimum(frame, len(angles) - 1)]


def raw_rollout(robot, seconds: float, runs: int = 1, tables=None) -> float:  # noqa: ANN001
    """Emulated seconds per CPU second of ``runs`` trajectories in one ``rollout`` (one
    thread): each the world's serpenoid (:func:`goals_at`), or, given ``tables`` (one
    (joint angles by frame, frame period in s) a run), those tables."""
    model, state, _ = raw_model(robot)
    data = mujoco.MjData(model)
    if tables is None:
        control = np.tile(serpenoid_controls(robot, model, seconds), (runs, 1, 1))
    else:
        control = np.stack([table_controls(model, a, p, seconds) for a, p in tables])
    initial = np.tile(state, (runs, 1))
    cpu = time.process_time()
    rollout.rollout(model, data, initial, control)
    return runs * seconds / (time.process_time() - cpu)


def raw_loop(robot, seconds: float) -> float:  # noqa: ANN001
    """Emulated seconds per CPU second of a Python loop over ``mj_step``, the same run."""
    model, state, _ = raw_model(robot)
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    controls = serpenoid_controls(robot, model, seconds)
    step, ctrl = mujoco.mj_step, data.ctrl
    cpu = time.process_time()
    for row in controls:
        ctrl[:] = row
        step(model, data)
    return seconds / (time.process_time() - cpu)


def whole_play(robot, table) -> float:  # noqa: ANN001
    """Emulated seconds per CPU second of a play as `sim predict --world mujoco` runs it."""
    from snakebot.link.transport import DxlClient
    from snakebot.workflows.predict import move_to_start, play, sim_url

    with DxlClient(sim_url(robot, ideal=False), echo=False) as client:
        bus = client.port.bus
        move_to_start(client, bus, robot, table.frames[0])
        cpu = time.process_time()
        record, *_ = play(client, bus, robot, table, ideal=False, world="mujoco")
        return float(record.t[-1]) / (time.process_time() - cpu)


def search_rate(runs: int) -> tuple[float, float, list[tuple[np.ndarray, float]]]:
    """(physics search evaluations per CPU second, seconds of emulated time per run, the
    runs' tables) of snake5 serpenoids of :data:`SEARCH_CYCLES` cycles at 50 Hz, as
    bench_search runs them; each table as (joint angles by frame, frame period in s), the
    very frames the search plays."""
    from snakebot.workflows.search import Settings
    from snakebot.workflows.search.evaluate import _frames, evaluate_many

    settings = Settings("snake5", "mujoco", SEARCH_CYCLES, 50.0)
    point = {"amplitude": math.radians(30), "omega": math.radians(360)}
    point |= {"delta": math.radians(60), "offset": 0.0}
    points = [
        dict(point, amplitude=math.radians(20 + 20 * k / max(1, runs - 1))) for k in range(runs)
    ]
    robot = load_robot("snake5")
    frames = [_frames(robot, settings, p) for p in points]
    tables = [(f.angles, f.period_ms / 1000.0) for f in frames]
    cpu = time.process_time()
    rows = evaluate_many(settings, points)
    spent = time.process_time() - cpu
    assert all(r["status"] == "ok" for r in rows), rows[0]["reason"]
    return runs / spent, frames[0].duration_s, tables


def median_of(rounds: int, ways: dict[str, Callable[[], float]]) -> dict[str, float]:
    runs: dict[str, list[float]] = {name: [] for name in ways}
    for _ in range(rounds):  # alternate, so load from other processes hits all alike
        for name, way in ways.items():
            runs[name].append(way())
    return {name: statistics.median(values) for name, values in runs.items()}


def main() -> int:
    quick = "--quick" in sys.argv
    rounds = 3 if quick else 5
    robot = load_robot("snake5")
    gait = serpenoid(robot, math.radians(30), math.pi, math.pi / 2, cycles=2, rate_hz=50)
    table = gait.gait_table()
    _, world = world_alone(robot, 0.1)  # its time steps
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(
        f"== snake5, MuJoCo step {world.timestep * 1e3:g} ms, control "
        f"{world.control_period * 1e3:g} ms, samples every {world.period * 1e3:g} ms; "
        f"emulated s per CPU s, median of {rounds}"
    )
    got = median_of(
        rounds,
        {
            "rollout": lambda: raw_rollout(robot, SECONDS),
            "loop": lambda: raw_loop(robot, SECONDS),
            "world": lambda: world_alone(robot, SECONDS)[0],
            "play": lambda: whole_play(robot, table),
        },
    )
    ratio = got["world"] / got["rollout"]
    tick_us = 1e6 * world.control_period
    print(f"   raw MuJoCo, rollout:        {got['rollout']:7.1f} x real time")
    print(f"   raw MuJoCo, mj_step loop:   {got['loop']:7.1f} x")
    print(
        f"   physics world (bus, no client): {got['world']:7.1f} x = {ratio:.2f} of the rollout "
        f"(goal {GOAL_WORLD}: {'met' if ratio >= GOAL_WORLD else 'MISS'}); per control tick "
        f"{tick_us / got['world']:.1f} us, of which MuJoCo {tick_us / got['rollout']:.1f} us"
    )
    print(
        f"   whole play (player, client, bus): {got['play']:7.1f} x = "
        f"{got['play'] / got['rollout']:.2f} of the rollout"
    )
    runs = 2 if quick else SEARCH_RUNS
    searched = []
    batched = []
    run_s = 0.0
    for _ in range(rounds):
        rate, run_s, tables = search_rate(runs)
        searched.append(rate)
        batched.append(raw_rollout(robot, run_s, runs, tables) / run_s)
    search, batch = statistics.median(searched), statistics.median(batched)
    met = "met" if search / batch >= GOAL_SEARCH else "MISS"
    print(
        f"== search, {runs} runs of {run_s:g} s: gait search --world mujoco {search:6.1f} runs/s "
        f"per core; one batched rollout of as many runs {batch:6.1f} runs/s = "
        f"{search / batch:.2f} (goal {GOAL_SEARCH}: {met})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
