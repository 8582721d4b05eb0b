"""Planning time for a target one body length away, against the 2 s goal.

For each robot family (trident, 3-link snake, snake5), ``make_plan`` plans to seeded
random targets exactly one body length away in any direction with a heading change up
to 60 degrees, timed on the wall clock, once for each board's table capacity (the
smallest board's is the default; the largest lets the planner try many more loops);
the worst time per robot and capacity is set against the goal, with the CPU time
beside it (which the machine's load moves less). Reference,
measured in the same run: one integration of the finished table as the controller
plays it (``table_motion``), the unit of work the planner repeats. A
target the 3-link snake's planner refuses is counted by its time to refuse (the
refusal is part of the command's answer), and reported.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from snakebot.facts.boards import TABLE_CAPACITY
from snakebot.model.gait.common import table_motion
from snakebot.model.plan import PlanRequest, Unreachable, body_length, make_plan
from snakebot.model.robots import load_robot

GOAL_S = 2.0
TARGETS = 3


def main() -> int:
    for name in ("trident", "snake3", "snake5"):
        for board in sorted(TABLE_CAPACITY, key=TABLE_CAPACITY.__getitem__):
            measure(name, board)
    return 0  # a speed goal is reported, not a failure of the run


def measure(name: str, board: str) -> None:
    """Plan for the seeded targets in a table of ``board``'s capacity; print the worst."""
    robot = load_robot(name)
    capacity = TABLE_CAPACITY[board]
    rng = np.random.default_rng(7)
    length = body_length(robot)
    worst, worst_cpu, refused, reference = 0.0, 0.0, 0, math.inf
    for _ in range(TARGETS):
        bearing = rng.uniform(-math.pi, math.pi)
        target = (
            length * math.cos(bearing),
            length * math.sin(bearing),
            rng.uniform(-1, 1) * math.radians(60),
        )
        t0, cpu0 = time.perf_counter(), time.process_time()
        try:
            plan = make_plan(PlanRequest(robot, target, capacity=capacity))
        except Unreachable:
            refused += 1
            plan = None
        worst = max(worst, time.perf_counter() - t0)
        worst_cpu = max(worst_cpu, time.process_time() - cpu0)
        if plan is not None:
            g = plan.gait
            t0 = time.perf_counter()
            table_motion(robot, robot.ticks_to_angles(g.ticks), g.period_ms / 1000, False)
            reference = min(reference, time.perf_counter() - t0)
    ratio = worst / GOAL_S
    verdict = "ok" if ratio <= 1 else "MISS"
    ref = f"{reference * 1e3:.1f} ms" if math.isfinite(reference) else "n/a"
    print(
        f"{name:8} one body length ({length:g}), {board:5} table ({capacity} B): worst of "
        f"{TARGETS} plans {worst:.3f} s ({worst_cpu:.3f} s of CPU), goal {GOAL_S:.1f} s, "
        f"ratio {ratio:.2f} {verdict}; one table integration {ref}"
        + (f"; {refused} refused" if refused else "")
    )


if __name__ == "__main__":
    sys.exit(main())
