"""Benchmark: `snakebot sim serve`'s memory stays flat after its first minute, each world.

Each world's server (`snakebot sim serve --world kinematic|mujoco`, the firmware on the
board sim serve emulates by default, ``--board cm530``: the CM-530's own image on the
emulated STM32F103RE inside the server's Python process; ``--board qemu``: the qemu
board's build in a QEMU of its own) drives the emulated robot, which samples its world
and the goals every 10 ms of bus time. The servers run in processes of their own, all at
once, for ``--minutes`` (default 3; the issue asks for 30: ``--minutes 30``). The
resident set size of each server's Python process (``VmRSS`` in ``/proc/<pid>/status``)
is read every ``--every`` seconds; on the cm530 board that is the whole server, on the
qemu board its QEMU, a process of its own, is shown beside. The reference, measured in
the same run, is the server's own size at the end of its first minute: the line gives
the growth after it (MB in all, MB a minute) and the ratio of the last size to it. The
goal: growth after the first minute under :data:`GOAL_MB` however long the run, which
holds when the history (the latest 600 s of samples) lives in preallocated ring
buffers. Each server plays a serpenoid gait in a loop (uploaded over its PC link,
`snakebot play --loop`), so the firmware, the servos and the world all work as in use;
``--still`` leaves the robot standing (the world samples as often either way).
``--csv FILE`` keeps every sample.

    .venv/bin/python bench/bench_serve_memory.py [--minutes 30] [--every 10] [--world mujoco]
        [--board cm530|qemu]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from snakebot.firmware import built_image
from snakebot.paths import REPO_ROOT
from snakebot.sim.serve import BOARDS, DEFAULT_BOARD, DEFAULT_IMAGES

GOAL_MB = 5.0
WARM_UP_S = 60.0
WORLDS = ("kinematic", "mujoco")
START_S = 120.0
GAIT = ["gait", "serpenoid", "snake5", "-A", "30deg", "-w", "180deg", "-d", "90deg"]
"""The gait each server plays (sim serve's default robot is snake5)."""


def firmware(board: str) -> str:
    """``board``'s default image in this checkout, built by ``make firmware`` if missing."""
    built = built_image(board, DEFAULT_IMAGES[board])
    if not built.exists():
        subprocess.run(["make", "-s", "-C", str(REPO_ROOT), "firmware"], check=True)
    return str(built)


def rss_mb(pid: int) -> float:
    """Resident set size of process ``pid`` in MB (0 once it has gone)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return 0.0
    for line in status.splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return 0.0


def children_mb(pid: int) -> float:
    """Resident set size of the direct children of ``pid`` (on the qemu board the
    server's QEMU; the cm530 board has none), in MB."""
    total = 0.0
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            kids = (task / "children").read_text().split()
        except OSError:
            continue
        total += sum(rss_mb(int(kid)) for kid in kids)
    return total


def snakebot(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "snakebot", *args], check=True, stdout=subprocess.DEVNULL)


def start(world: str, board: str, image: str, gait: Path | None) -> subprocess.Popen[str]:
    """``sim serve`` on ``world`` and ``board``, playing ``gait`` in a loop if given."""
    command = [sys.executable, "-m", "snakebot", "sim", "serve", "--world", world]
    command += ["--board", board, "--firmware", image, "--report", "0", "--json"]
    server = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
    assert server.stdout is not None
    deadline = time.monotonic() + START_S
    line = server.stdout.readline()  # where everything is: the server is up
    if not line or time.monotonic() > deadline:
        raise SystemExit(f"error: `snakebot sim serve --world {world}` did not start")
    if gait is not None:
        port = json.loads(line)["pc_link"]
        snakebot("upload", str(gait), "--port", port)
        snakebot("play", "--port", port, "--loop")
    return server


def travelled(server: subprocess.Popen[str]) -> float:
    """How far the body went, in m: the last pose the stopped server printed."""
    assert server.stdout is not None
    x = y = 0.0
    for line in server.stdout.read().splitlines():
        pose = json.loads(line)
        x, y = pose.get("x", x), pose.get("y", y)
    server.wait()
    return math.hypot(x, y)


def summary(world: str, points: list[tuple[float, float, float]], board: str) -> str:
    """One line: the size at the start, after the first minute and at the end, the growth
    after the first minute in all and a minute, its ratio and a coarse trace (and on the
    qemu board the size of its QEMU)."""
    first, (end, last, qemu) = points[0][1], points[-1]
    trace = " ".join(f"{rss:.1f}" for _, rss, _ in points[:: max(1, len(points) // 12)])
    if end < WARM_UP_S:
        return f"   {world:<9}: {first:.1f} -> {last:.1f} MB (shorter than the warm-up)"
    at, warm = next((t, rss) for t, rss, _ in points if t >= WARM_UP_S)
    growth = last - warm
    rate = growth / max((end - at) / 60, 1e-9)
    verdict = "met" if growth < GOAL_MB else "MISS"
    return (
        f"   {world:<9}: start {first:.1f} MB, at {at / 60:.1f} min {warm:.1f} MB, at "
        f"{end / 60:.1f} min {last:.1f} MB: {growth:+.1f} MB after the first minute "
        f"({rate:+.3f} MB/min, {last / warm:.3f}x its size at 1 min; goal < {GOAL_MB:g} MB: "
        f"{verdict}){f'; its QEMU {qemu:.1f} MB' if board == 'qemu' else ''}; trace {trace}"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=3.0)
    parser.add_argument("--every", type=float, default=10.0)
    parser.add_argument("--world", choices=WORLDS, action="append", help="(default: both)")
    parser.add_argument(
        "--board", choices=BOARDS, default=DEFAULT_BOARD, help="(default: %(default)s)"
    )
    parser.add_argument("--firmware", help="the board's image (default: this checkout's)")
    parser.add_argument(
        "--csv", type=Path, help="keep every sample (seconds, world, server MB, its QEMU MB)"
    )
    parser.add_argument("--still", action="store_true", help="play no gait")
    args = parser.parse_args()
    worlds = tuple(args.world or WORLDS)
    image = args.firmware or firmware(args.board)
    doing = "standing still" if args.still else "playing a serpenoid gait in a loop"
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(
        f"== sim serve, {', '.join(worlds)}, {args.board} board, {doing}, for {args.minutes:g} min"
    )
    print(f"   RSS every {args.every:g} s")
    gait = None
    if not args.still:
        gait = Path(tempfile.mkdtemp(prefix="bench-serve-memory-")) / "walk.gait"
        snakebot(*GAIT, "--cycles", "1", "-o", str(gait))
    # terminated (as by a `make bench` stopped with kill), stop the servers on the way out
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    servers = {world: start(world, args.board, image, gait) for world in worlds}
    began = time.monotonic()
    series: dict[str, list[tuple[float, float, float]]] = {world: [] for world in worlds}
    log = args.csv.open("w") if args.csv else None
    try:
        while True:
            elapsed = time.monotonic() - began
            for world, server in servers.items():
                if server.poll() is not None:
                    raise SystemExit(f"error: the {world} server stopped")
                point = (elapsed, rss_mb(server.pid), children_mb(server.pid))
                series[world].append(point)
                if log:
                    row = f"{elapsed:.1f},{world},{point[1]:.2f},{point[2]:.2f}"
                    print(row, file=log, flush=True)
            if elapsed >= args.minutes * 60:
                break
            time.sleep(min(args.every, max(0.0, args.minutes * 60 - elapsed)))
    finally:
        for server in servers.values():
            server.send_signal(signal.SIGINT)
        went = {world: travelled(server) for world, server in servers.items()}
        if log:
            log.close()
    for world in worlds:
        print(summary(world, series[world], args.board) + f"; the body went {went[world]:.1f} m")
    return 0  # a benchmark reports; the verdicts are in the lines


if __name__ == "__main__":
    sys.exit(main())
