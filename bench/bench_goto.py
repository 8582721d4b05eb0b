"""The closed loop on the physics world, seeded targets: where it ends and what it costs.

`sim goto ROBOT --to X,Y,THETA --world mujoco` for each robot family (trident, 3-link
snake, snake5) at the seeded random targets the plan tests draw (seeds 31..36, a quarter
to one body length away, heading change up to 60 degrees; `tests/support/plan_support.py`),
through the library call the command makes. Per target: the final error as a multiple of
the tolerance (position, heading), the loops or cycles played, the simulated time and the
CPU time. The goal is to end within twice the tolerance; a target that ends outside it
is printed as MISS and counted. `make test` plays one of these seeds per family
(`tests/workflows/test_plan_goto.py`); this is the whole campaign. Reference, measured
in the same run: the simulated time itself (CPU per simulated second).

``--robot NAME`` and ``--seed N`` (each may repeat) play only those robots and seeds.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "support"))

from plan_support import targets  # noqa: E402

from snakebot.model.robots import load_robot  # noqa: E402
from snakebot.workflows.goto import goto  # noqa: E402

SEEDS = range(31, 37)
ROBOTS = ("trident", "snake3", "snake5")
WITHIN = 2.0  # the goal: within twice the tolerance


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", action="append", choices=ROBOTS, help="only this robot")
    parser.add_argument("--seed", action="append", type=int, help="only this seed")
    args = parser.parse_args()
    misses, total, cpu_total = 0, 0, 0.0
    for name in args.robot or ROBOTS:
        robot = load_robot(name)
        for seed in args.seed or SEEDS:
            target = targets(name, seed, 1)[0]
            cpu0 = time.process_time()
            report = goto(robot, target, world="mujoco").summary()
            cpu = time.process_time() - cpu0
            e = report["error"]
            pos = e["position"] / e["position_tolerance"]
            head = abs(e["heading_rad"]) / e["heading_tolerance_rad"]
            ok = pos <= WITHIN and head <= WITHIN
            misses += not ok
            total += 1
            cpu_total += cpu
            sim_s = report["duration_s"]
            print(
                f"{name:8} seed {seed}: error {pos:.2f}x, {head:.2f}x the tolerance "
                f"({'ok' if ok else 'MISS'}), {report['iterations']} loops/cycles, "
                f"{sim_s:.1f} s simulated, {cpu:.1f} s CPU "
                f"({cpu / sim_s if sim_s else 0:.2f} s per simulated second)",
                flush=True,
            )
    print(
        f"goto on MuJoCo: {total - misses} of {total} targets within {WITHIN:g}x the "
        f"tolerance, {misses} missed; {cpu_total:.0f} s of CPU in all"
    )
    return 0  # a miss is reported, not a failure of the run


if __name__ == "__main__":
    sys.exit(main())
