"""Benchmark: `snakebot sim serve`'s memory stays flat after its first minute, both worlds.

Each world's server (`snakebot sim serve --world kinematic|mujoco`, the firmware in QEMU
driving the emulated robot, which samples its world and the goals every 10 ms of bus
time) runs in a process of its own, both at once, for ``--minutes`` (default 3; the
issue asks for 30: ``--minutes 30``). The resident set size of each server's Python
process (``VmRSS`` in ``/proc/<pid>/status``; QEMU is a process of its own and not
counted) is read every ``--every`` seconds. The goal: growth from the end of the first
minute to the end under :data:`GOAL_MB`, while the history (the latest 600 s of samples)
is kept in preallocated ring buffers. The robot stands still: the world samples as much
either way.

    .venv/bin/python bench/bench_serve_memory.py [--minutes 30] [--every 10]
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

GOAL_MB = 5.0
WARM_UP_S = 60.0
WORLDS = ("kinematic", "mujoco")
START_S = 120.0


def firmware() -> str:
    """The qemu board's firmware: this checkout's build, else ``make firmware``'s."""
    built = Path(__file__).resolve().parent.parent / "build" / "qemu" / "firmware.elf"
    if not built.exists():
        subprocess.run(["make", "-s", "-C", str(built.parents[2]), "firmware"], check=True)
    return str(built)


def rss_mb(pid: int) -> float:
    """Resident set size of process ``pid`` in MB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError(f"no VmRSS for process {pid}")


def start(world: str, image: str) -> subprocess.Popen[str]:
    command = [sys.executable, "-m", "snakebot", "sim", "serve", "--world", world]
    command += ["--firmware", image, "--report", "0", "--json"]
    server = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
    assert server.stdout is not None
    deadline = time.monotonic() + START_S
    line = server.stdout.readline()  # where everything is: the server is up
    if not line or time.monotonic() > deadline:
        raise SystemExit(f"error: `snakebot sim serve --world {world}` did not start")
    return server


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=3.0)
    parser.add_argument("--every", type=float, default=10.0)
    parser.add_argument("--firmware", help="the firmware image (default: this checkout's)")
    args = parser.parse_args()
    image = args.firmware or firmware()
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(f"== sim serve, both worlds at once for {args.minutes:g} min; RSS every {args.every:g} s")
    servers = {world: start(world, image) for world in WORLDS}
    began = time.monotonic()
    series: dict[str, list[tuple[float, float]]] = {world: [] for world in WORLDS}
    try:
        while (elapsed := time.monotonic() - began) < args.minutes * 60:
            for world, server in servers.items():
                if server.poll() is not None:
                    raise SystemExit(f"error: the {world} server stopped")
                series[world].append((elapsed, rss_mb(server.pid)))
            time.sleep(args.every)
        for world, server in servers.items():
            series[world].append((time.monotonic() - began, rss_mb(server.pid)))
    finally:
        for server in servers.values():
            server.send_signal(signal.SIGINT)
        for server in servers.values():
            server.wait()
    for world in WORLDS:
        points = series[world]
        warm = (
            next(rss for t, rss in points if t >= WARM_UP_S) if points[-1][0] >= WARM_UP_S else None
        )
        first, last = points[0][1], points[-1][1]
        trace = " ".join(f"{rss:.1f}" for _, rss in points[:: max(1, len(points) // 12)])
        if warm is None:
            print(f"   {world:<9}: {first:.1f} -> {last:.1f} MB (shorter than the warm-up)")
            continue
        growth = last - warm
        met = growth < GOAL_MB
        print(
            f"   {world:<9}: start {first:.1f} MB, at 1 min {warm:.1f} MB, at "
            f"{points[-1][0] / 60:.1f} min {last:.1f} MB: +{growth:.1f} MB after the first "
            f"minute (goal < {GOAL_MB:g}: {'met' if met else 'MISS'}); trace {trace}"
        )
    return 0  # a benchmark reports; the verdicts are in the lines


if __name__ == "__main__":
    sys.exit(main())
