"""Benchmark: start-up CPU time of the command line against its references, measured in
the same run.

* `snakebot --help` against a bare click application's `--help` (one group, no
  commands), goal at most :data:`HELP_GOAL` times;
* a command that needs numpy, `snakebot gait serpenoid snake5 --help` (its options
  parse angles with the model's expressions), against `python -c 'import numpy'`, goal at
  most :data:`NUMPY_GOAL` times.

Each is a fresh interpreter; its CPU time (user + system, from the children's resource
usage) counts, not the wall clock, since the machine may be shared. Rounds alternate
between the four, and the lines give the medians. ``tests/cli/test_startup.py`` keeps the
module counts that make these figures.

    .venv/bin/python bench/bench_startup.py [--quick]
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys

HELP_GOAL = 2.0
NUMPY_GOAL = 1.5
BARE_CLICK = """
import click
@click.group()
def app() -> None:
    pass
app(["--help"])
"""
RUNS = {
    "bare click --help": [sys.executable, "-c", BARE_CLICK],
    "snakebot --help": [sys.executable, "-m", "snakebot", "--help"],
    "import numpy": [sys.executable, "-c", "import numpy"],
    "snakebot gait serpenoid --help": [
        *(sys.executable, "-m", "snakebot", "gait", "serpenoid", "snake5", "--help"),
    ],
}


def cpu_s(command: list[str]) -> float:
    """CPU seconds a fresh process running ``command`` takes."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> int:
    rounds = 5 if "--quick" in sys.argv else 15
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    times: dict[str, list[float]] = {name: [] for name in RUNS}
    for command in RUNS.values():  # warm the file cache and the .pyc files
        cpu_s(command)
    for _ in range(rounds):  # alternate, so load from other processes hits all alike
        for name, command in RUNS.items():
            times[name].append(cpu_s(command))
    got = {name: statistics.median(values) for name, values in times.items()}
    print(f"== start-up CPU time, median of {rounds} interleaved rounds")
    for name, value in got.items():
        print(f"   {name:<32} {value * 1e3:6.0f} ms")
    pairs = (
        ("snakebot --help", "bare click --help", HELP_GOAL),
        ("snakebot gait serpenoid --help", "import numpy", NUMPY_GOAL),
    )
    for ours, reference, goal in pairs:
        ratio = got[ours] / got[reference]
        verdict = "met" if ratio <= goal else "MISS"
        print(f"   {ours} / {reference}: {ratio:.2f} (goal <= {goal:g}: {verdict})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
