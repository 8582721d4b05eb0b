"""Benchmark: gait search throughput and how it scales.

1. Evaluations per second per core of one search run, in this process (CPU time, so
   other processes on the machine count less): the kinematic world (snake5, a 3-cycle
   serpenoid; goal 1000/s) and the physics world (the same 3-cycle run in MuJoCo on the
   emulated bus; goal 5/s); each the fastest of a few windows of runs, since load from
   elsewhere only adds time.
2. Parallel efficiency from 1 to 2 workers (goal 80 %): the same kinematic grid on a
   local process pool and on a Dask LocalCluster (loopback), each with 1 then 2 workers;
   efficiency = T(1) / (2 T(2)), both pools started and warmed before the clock starts,
   then timed in turn, round after round (each its fastest round).

Ratios are against the goals; a missed goal prints MISS. The machine may be shared:
the load average is printed with the figures.

    .venv/bin/python bench/bench_search.py [--quick]
"""

from __future__ import annotations

import math
import os
import sys
import time

from snakebot.workflows.search import LocalRunner, Request, Search, Settings, Space
from snakebot.workflows.search.evaluate import evaluate_many
from snakebot.workflows.search.runner import DaskRunner, Runner

GOAL_KINEMATIC = 1000.0
GOAL_PHYSICS = 5.0
GOAL_EFFICIENCY = 0.80
ROUNDS = 7
"""Windows timed for the runs per CPU second; the fastest counts (per_core)."""
CYCLES = 3
POINT = {
    "amplitude": math.radians(30),
    "omega": math.radians(360),
    "delta": math.radians(60),
    "offset": 0.0,
}


def verdict(value: float, goal: float) -> str:
    return f"ratio {value / goal:.2f}" + ("" if value >= goal else "  MISS")


def per_core(worlds: dict[str, int], rounds: int) -> dict[str, float]:
    """Runs per CPU second of this process in each world (its name: the runs of a
    window), after one warm-up run: the fastest of ``rounds`` windows, the worlds' windows
    interleaved, so that each world's are spread over the whole measurement. On this
    shared virtual machine the same work costs up to 1.8x the CPU time for seconds at a
    time (from outside the guest; see bench_kinematics.fastest): one window of 1000
    kinematic runs read 840/s where the next four read 1210 to 1290/s. Other load only
    ever adds time, so the fastest window is what a run costs; but a slow spell can
    outlast windows taken back to back (seven read 1001/s at load 0.2, then 1682/s and
    1769/s in the next two processes), so they are spread out."""
    settings = {world: Settings("snake5", world, CYCLES, 50.0) for world in worlds}
    points = {}
    for world, runs in worlds.items():
        evaluate_many(settings[world], [POINT])
        points[world] = [
            {**POINT, "amplitude": math.radians(20 + 20 * k / max(1, runs - 1))}
            for k in range(runs)
        ]
    best = dict.fromkeys(worlds, math.inf)
    for _ in range(rounds):
        for world in worlds:
            cpu0 = time.process_time()
            rows = evaluate_many(settings[world], points[world])
            best[world] = min(best[world], time.process_time() - cpu0)
            assert all(r["status"] == "ok" for r in rows), rows[0]["reason"]
    return {world: worlds[world] / best[world] for world in worlds}


def timed_search(runner: Runner, count: int) -> float:
    """Wall time of a kinematic grid of ``count`` x 10 candidates on ``runner``."""
    space = Space.parse((f"A=20deg:40deg:{count}", "delta=10deg:150deg:10", "omega=360deg"))
    request = Request(Settings("snake5", "kinematic", CYCLES, 50.0), space)
    Search(
        Request(request.settings, Space.parse(("A=30deg:31deg:4", "delta=1", "omega=6"))), runner
    ).run()
    t0 = time.perf_counter()
    Search(request, runner).run()
    return time.perf_counter() - t0


def efficiency(make, count: int, rounds: int) -> tuple[float, float, float]:  # noqa: ANN001
    """T(1), T(2) and T(1) / (2 T(2)): both runners started first, then timed in turn
    (1 then 2 workers, then 2 then 1), round after round, each its fastest round, so
    that a slow spell of the machine (seen to last seconds on this virtual machine)
    falls on both alike."""
    runners: dict[int, Runner] = {}
    try:
        for workers in (1, 2):
            runners[workers] = make(workers)
        times = dict.fromkeys(runners, math.inf)
        for r in range(rounds):
            for workers in (1, 2) if r % 2 == 0 else (2, 1):
                times[workers] = min(times[workers], timed_search(runners[workers], count))
    finally:
        for runner in runners.values():
            runner.close()
    return times[1], times[2], times[1] / (2 * times[2])


def dask_runner(workers: int) -> Runner:
    import logging

    from distributed import LocalCluster

    cluster = LocalCluster(
        silence_logs=logging.ERROR,
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    )
    runner = DaskRunner(cluster.scheduler_address)
    close = runner.close

    def close_both() -> None:
        close()
        cluster.close()

    runner.close = close_both  # type: ignore[method-assign]
    return runner


def main() -> int:
    quick = "--quick" in sys.argv
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    rounds = 2 if quick else ROUNDS
    rates = per_core({"kinematic": 300 if quick else 1000, "mujoco": 3 if quick else 10}, rounds)
    kin, phys = rates["kinematic"], rates["mujoco"]
    print(
        f"== one run: snake5 serpenoid, {CYCLES} cycles of 1 s at 50 Hz, per CPU second "
        f"(the fastest of {rounds} windows, the two worlds' interleaved)"
    )
    print(
        f"   kinematic world: {kin:8.1f} runs/s/core "
        f"(goal {GOAL_KINEMATIC:.0f}: {verdict(kin, GOAL_KINEMATIC)})"
    )
    print(
        f"   physics world:   {phys:8.2f} runs/s/core "
        f"(goal {GOAL_PHYSICS:.0f}: {verdict(phys, GOAL_PHYSICS)})"
    )
    # about 3 s on one worker (a kinematic run takes about 0.7 ms; a grid of 2000, what it
    # was when a run took 12 ms, timed the pools' dispatch more than the search), in
    # several short rounds rather than a few long ones: this machine's slow spells last
    # seconds, and each side counts its fastest round. Ten: with six, one make bench read
    # Dask's two workers at 2.59 s where six runs outside it read 1.84 to 2.21 s
    count, rounds = (60, 2) if quick else (400, 10)
    print(
        f"== parallel efficiency, 1 -> 2 workers: a kinematic grid of {count * 10} runs, "
        f"best of {rounds} rounds, 1 and 2 workers in turn"
    )
    for label, make in (("local process pool", LocalRunner), ("Dask LocalCluster", dask_runner)):
        t1, t2, eff = efficiency(make, count, rounds)
        print(
            f"   {label:19} {t1:6.2f} s -> {t2:6.2f} s: {100 * eff:5.1f} % "
            f"(goal {100 * GOAL_EFFICIENCY:.0f} %: {verdict(eff, GOAL_EFFICIENCY)})"
        )
    print(f"== load average after: {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
