"""Benchmark: the MuJoCo world's speed, in process and behind the firmware in QEMU.

1. In process, the host as bus master: a snake5 serpenoid table (20 ms frames, two
   cycles) played as `snakebot sim predict --world mujoco` plays it, at the physics
   world's default step (the one tests/sim/test_physics_convergence.py checks).
   Printed: emulated seconds per wall second (goal: at least 100x), beside the kinematic
   world measured in the same run as the reference, and the limit: MuJoCo's own rollout
   of the same model, step and gait (bench_physics_raw.py). Best of several rounds (the machine
   is shared).
2. Behind the firmware: `snakebot sim serve --world mujoco` as the demo runs it (QEMU
   playing an uploaded gait in real time); printed: the share of one core the physics
   world's steps take (goal: under 10 %), from the time spent in them over the wall time.

    .venv/bin/python bench/bench_physics.py [--quick]
"""

from __future__ import annotations

import math
import os
import sys
import time

import numpy as np
from bench_physics_raw import raw_rollout  # the benches' folder is on the path

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.link.transport import DxlClient
from snakebot.model.gait import serpenoid
from snakebot.model.robots import load_robot
from snakebot.sim.physics.world import PhysicsWorld
from snakebot.workflows.predict import move_to_start, play, sim_url

GOAL_REALTIME = 100.0
GOAL_CORE_SHARE = 0.10
SERVE_SECONDS = 6.0


def in_process(table, robot, world: str) -> tuple[float, float]:  # noqa: ANN001
    """Emulated seconds of one play in ``world`` per wall second and per CPU second of
    this process (the second depends less on what else the machine runs)."""
    with DxlClient(sim_url(robot, ideal=False), echo=False) as client:
        bus = client.port.bus
        move_to_start(client, bus, robot, table.frames[0])
        cpu0 = time.process_time()
        record, _, wall, _ = play(client, bus, robot, table, ideal=False, world=world)
        cpu = time.process_time() - cpu0
        emulated = float(record.t[-1])
        return emulated / wall, emulated / cpu if cpu > 0 else float("inf")


def behind_firmware(table, robot) -> tuple[float, float]:  # noqa: ANN001
    """(share of a core in the physics world's steps, firmware playback rate) while QEMU
    plays ``table`` in a loop for SERVE_SECONDS."""
    from snakebot.link.controller.client import ControllerClient
    from snakebot.link.controller.playback import play as play_table
    from snakebot.link.controller.playback import stop
    from snakebot.link.controller.upload import upload_gait
    from snakebot.sim.serve import EmulatedRobot

    spent = [0.0]
    tick = PhysicsWorld._tick

    def timed(self: PhysicsWorld, t: float) -> None:
        t0 = time.perf_counter()
        tick(self, t)
        spent[0] += time.perf_counter() - t0

    PhysicsWorld._tick = timed  # type: ignore[method-assign]
    emulated = EmulatedRobot(robot, world="mujoco", board="qemu")
    try:
        info = emulated.start()
        with ControllerClient.open(info.pc_link) as ctl:
            upload_gait(ctl, table, allow_new_servos=True)
            spent[0] = 0.0
            world0, wall0 = emulated.world_time(), time.perf_counter()
            play_table(ctl, loop=True)
            time.sleep(SERVE_SECONDS)
            wall = time.perf_counter() - wall0
            world = emulated.world_time() - world0
            share = spent[0] / wall
            stop(ctl)
    finally:
        emulated.stop()
        PhysicsWorld._tick = tick  # type: ignore[method-assign]
    return share, world / wall


def main() -> int:
    quick = "--quick" in sys.argv
    rounds = 3 if quick else 8
    robot = load_robot("snake5")
    gait = serpenoid(robot, math.radians(30), math.pi, math.pi / 2, cycles=2, rate_hz=50)
    table = gait.gait_table()
    seconds = table.frame_count * table.frame_period_ms / 1000.0
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(
        f"== snake5 serpenoid, {table.frame_count} frames every {table.frame_period_ms} ms "
        f"({seconds:.1f} s of bus time), host as master, best of {rounds}"
    )
    best = {"kinematic": 0.0, "mujoco": 0.0}
    best_cpu = dict(best)
    for _ in range(rounds):  # alternate, so load from other processes hits both alike
        for world in best:
            wall_rtf, cpu_rtf = in_process(table, robot, world)
            best[world] = max(best[world], wall_rtf)
            best_cpu[world] = max(best_cpu[world], cpu_rtf)
    print(f"   kinematic world (reference): {best['kinematic']:7.1f} x real time")
    print(
        f"   MuJoCo world:                {best['mujoco']:7.1f} x real time "
        f"(goal {GOAL_REALTIME:.0f} x: ratio {best['mujoco'] / GOAL_REALTIME:.2f}; "
        f"{best['mujoco'] / best['kinematic']:.2f} of the kinematic world's speed)"
    )
    print(
        f"   per CPU second of this process: kinematic {best_cpu['kinematic']:.1f} x, "
        f"MuJoCo {best_cpu['mujoco']:.1f} x (wall figures fall when other processes "
        "share the cores)"
    )
    # the limit: MuJoCo alone on the same model, step and table (bench_physics_raw.py)
    angles = robot.ticks_to_angles(np.asarray(table.frames))
    motion = [(angles, table.frame_period_ms / 1000.0)]
    limit = max(raw_rollout(robot, seconds, 1, motion) for _ in range(rounds))
    beyond = " the goal is above MuJoCo's own speed at this step" if limit < GOAL_REALTIME else ""
    print(
        f"   MuJoCo alone (its rollout of the same model, step and gait): {limit:.1f} x real "
        f"time per CPU second, the most any world on it can reach;{beyond}"
    )
    met = best["mujoco"] >= GOAL_REALTIME
    share, rate = behind_firmware(table, robot)
    print(
        f"== the firmware in QEMU playing it in real time ({rate:.2f}x wall clock) for "
        f"{SERVE_SECONDS:.0f} s on the MuJoCo world"
    )
    print(
        f"   the physics world's steps take {100 * share:.1f} % of a core "
        f"(goal under {100 * GOAL_CORE_SHARE:.0f} %: ratio {share / GOAL_CORE_SHARE:.2f})"
    )
    met = met and share < GOAL_CORE_SHARE
    print("GOAL MET" if met else "BELOW GOAL")
    return 0


if __name__ == "__main__":
    sys.exit(main())
