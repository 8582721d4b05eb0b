"""Benchmark: `make test`'s wall time against its goal (five minutes on an idle machine),
with the firmware-in-the-loop tests on both boards (the CM-530's own image on the emulated
STM32F103RE, and the qemu board's build under QEMU).

Runs `make test` in this checkout (its set-up already done, as after `make demo`), prints
each stage's result line, the whole time against :data:`GOAL_S`, and how many of the
suite's tests run on each board (test IDs naming it). The machine should be idle: `make
test` itself notices other work and then runs its timing-sensitive stages one test at a
time, which takes longer (the figure says which mode it ran in).

    .venv/bin/python bench/bench_test_time.py
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

GOAL_S = 300.0
ROOT = Path(__file__).resolve().parents[1]
BOARDS = ("cm530", "qemu")


def board_tests() -> dict[str, int]:
    """How many collected tests name each board in their ID (a parameter, a file or a
    test's name)."""
    out = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    ).stdout
    ids = [line for line in out.splitlines() if "::" in line]
    return {board: sum(1 for i in ids if board in i.lower()) for board in BOARDS}


STAGE_LOGS = ("qemu", "serial", "campaigns", "late", "fuzz", "wheel")
"""The stages whose output `make test` keeps in build/test-NAME.log (the parallel stage
prints its own)."""


def stage_summaries(stdout: str, since: float) -> dict[str, str]:
    """Each stage's pytest summary line (its counts and time): the parallel stage's from
    ``stdout``, the others' from their logs written after ``since`` (a wall-clock time;
    an older log is an earlier run's)."""
    out = {}
    summary = r"=+ (\d+ (?:passed|failed|errors?|skipped)[^=]*?) =+\s*$"
    if found := re.search(summary, stdout, re.MULTILINE):
        out["parallel"] = found.group(1)
    for name in STAGE_LOGS:
        path = ROOT / "build" / f"test-{name}.log"
        fresh = path.exists() and path.stat().st_mtime >= since
        tail = path.read_text(errors="replace").strip().splitlines()[-1:] if fresh else []
        out[name] = tail[0].strip(" =") if tail else "not run"
    return out


def main() -> int:
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    env = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL")}
    t0, began = time.monotonic(), time.time()
    run = subprocess.run(
        ["make", "--no-print-directory", "test"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    wall = time.monotonic() - t0
    lines = run.stdout.splitlines()
    busy = any("other work keeps" in line for line in lines)
    for name, summary in stage_summaries(run.stdout, began).items():
        print(f"   {name:9} {summary}")
    for line in lines:  # each failed test, by name (a failed stage prints its log whole)
        if line.startswith(("FAILED ", "ERROR ")):
            print(f"     {line}")
    counts = board_tests()
    verdict = "met" if wall <= GOAL_S and run.returncode == 0 else "MISS"
    print(
        f"   make test: {wall:.0f} s ({'busy machine mode' if busy else 'idle machine mode'}), "
        f"exit {run.returncode}; goal {GOAL_S:.0f} s: ratio {wall / GOAL_S:.2f} ({verdict})"
    )
    print("   tests naming a board: " + ", ".join(f"{board} {n}" for board, n in counts.items()))
    print(f"== load average after: {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
