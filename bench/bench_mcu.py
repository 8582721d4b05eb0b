"""Benchmark: the emulated CM-530 (the exact cm530 image on the emulated STM32F103RE)
playing a gait on the snake5's 4 emulated servos, against real time, with the QEMU board
doing the same beside it.

1. cm530: the gait is uploaded and started through the PC link in real time, then the
   board (chip, bus, servos, world) runs unpaced, as fast as this process can, for
   PLAY_SECONDS of emulated time. Printed: emulated seconds per CPU second and per wall
   second (goal: at least 5x real time).
2. qemu: `sim serve`'s QEMU plays the same gait in real time (QEMU's clock is the host's);
   printed: its equivalent figure, wall seconds over the CPU seconds QEMU and the bus
   server used (how many times real time it could run if it ran flat out).

    .venv/bin/python bench/bench_mcu.py [--quick]
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time
from collections.abc import Iterator

from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.playback import play, stop
from snakebot.link.controller.upload import upload_gait
from snakebot.model.gait import serpenoid
from snakebot.model.robots import load_robot
from snakebot.sim.serve import EmulatedRobot

GOAL_REALTIME = 5.0
GOAL_SERVE_SHARE = 0.30
"""`sim serve --board cm530` at real time: at most this share of one core."""
SERVE_SECONDS = 20.0
MARGIN_ENV = "SNAKEBOT_MARGIN_MS"


def _cpu_of(pid: int) -> float:
    """CPU seconds (user + system) process ``pid`` has used."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@contextlib.contextmanager
def playing(board: str, table) -> Iterator[tuple[EmulatedRobot, ControllerClient]]:  # noqa: ANN001
    """The snake5 on ``board`` with ``table`` uploaded and looping, and a client to it."""
    robot = EmulatedRobot("snake5", board=board)
    try:
        info = robot.start()
        with ControllerClient.open(info.pc_link) as ctl:
            upload_gait(ctl, table, allow_new_servos=True)
            play(ctl, loop=True)
            yield robot, ctl
    finally:
        robot.stop()


def cm530(table, seconds: float) -> tuple[float, float, int]:  # noqa: ANN001
    """(emulated s per CPU s, per wall s, bus bytes) of the cm530 board playing ``table``."""
    with playing("cm530", table) as (robot, _ctl):
        fw = robot._mcu  # noqa: SLF001 - the benchmark drives the board itself
        assert fw is not None
        fw.stop()  # the thread stops; the board stays, playing, in this thread's hands
        board = fw.board
        sent0 = board.bus_stats.sent
        cpu0, wall0, t0 = time.process_time(), time.perf_counter(), board.now()
        board.run_until(t0 + seconds)
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
        return seconds / cpu, seconds / wall, board.bus_stats.sent - sent0


def serve_share(table, seconds: float) -> float:  # noqa: ANN001
    """The share of one core this process takes while the cm530 board plays ``table`` in
    real time, as `sim serve` runs it (its runner thread; nothing else works meanwhile)."""
    with playing("cm530", table) as (_robot, ctl):
        time.sleep(1.0)  # past the upload's and play's own work
        cpu0, wall0 = time.process_time(), time.perf_counter()
        time.sleep(seconds)
        share = (time.process_time() - cpu0) / (time.perf_counter() - wall0)
        stop(ctl)
    return share


def qemu(table, seconds: float) -> float:  # noqa: ANN001
    """Wall seconds per CPU second (QEMU's and this process's) while QEMU plays ``table``."""
    with playing("qemu", table) as (robot, ctl):
        pid = robot.info.qemu_pid
        cpu0, own0, wall0 = _cpu_of(pid), time.process_time(), time.perf_counter()
        time.sleep(seconds)
        cpu = _cpu_of(pid) - cpu0 + time.process_time() - own0
        wall = time.perf_counter() - wall0
        stop(ctl)
    return wall / cpu


def main() -> int:
    quick = "--quick" in sys.argv
    seconds = 2.0 if quick else 6.0
    os.environ.setdefault(MARGIN_ENV, "3000")  # the emulators share a loaded machine
    robot = load_robot("snake5")
    table = serpenoid(robot, math.radians(30), math.pi, math.pi / 2, cycles=2, rate_hz=50)
    table = table.gait_table()
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(f"== snake5 serpenoid on 4 servos, looped, {seconds:.0f} s of emulated play")
    per_cpu, per_wall, sent = cm530(table, seconds)
    print(
        f"   cm530 (emulated STM32F103RE): {per_cpu:5.2f} x real time per CPU second, "
        f"{per_wall:5.2f} x per wall second ({sent / seconds:.0f} bus bytes/s sent) "
        f"(goal {GOAL_REALTIME:.0f} x: ratio {per_cpu / GOAL_REALTIME:.2f})"
    )
    q = qemu(table, seconds)
    print(f"   qemu board (QEMU, real time):   {q:5.2f} x real time per CPU second")
    share = serve_share(table, seconds if quick else SERVE_SECONDS)
    verdict = "met" if share < GOAL_SERVE_SHARE else "MISS"
    print(
        f"   cm530 as sim serve runs it, in real time: {share * 100:4.1f} % of a core "
        f"(goal under {GOAL_SERVE_SHARE * 100:.0f} %: {verdict})"
    )
    met = per_cpu >= GOAL_REALTIME and share < GOAL_SERVE_SHARE
    print("GOAL MET" if met else "MISS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
