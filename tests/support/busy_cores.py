"""How many cores other work keeps busy now: the CPU time all processes used over one
second, from /proc/stat, in cores (0.0 on an idle machine, about 2.0 beside two busy
processes). `make test` reads it before it starts anything of its own and, on a busy
machine, runs its real-time stages one test at a time. Prints 0.0 where /proc/stat
cannot be read."""

from __future__ import annotations

import os
import time


def busy_and_total() -> tuple[int, int]:
    with open("/proc/stat", encoding="ascii") as f:
        fields = [int(v) for v in f.readline().split()[1:]]
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)  # idle, iowait
    return sum(fields) - idle, sum(fields)


def busy_cores(seconds: float = 1.0) -> float:
    try:
        busy0, total0 = busy_and_total()
        time.sleep(seconds)
        busy1, total1 = busy_and_total()
    except (OSError, ValueError, IndexError):
        return 0.0
    if total1 <= total0:
        return 0.0
    return (busy1 - busy0) / (total1 - total0) * (os.cpu_count() or 1)


if __name__ == "__main__":
    print(f"{busy_cores():.1f}")
