"""Benchmark: the emulated bus in a closed loop, and how its cost grows with the servos.

Each 10 ms control tick the master sends one SYNC_WRITE of goal positions to every
servo and then READs every servo's Present Position, waiting for each status packet:
the heaviest pattern a controller uses (the firmware reads one servo a tick). Return
Delay Time 0, 1 Mbps, no faults. Measured at 5, 18 and 50 servos:

* the emulator alone: the master is a bare loop on the bus's own interface (packets
  built once, ``master_write``, then ``master_receive``, the timed read the sim://
  port makes), so the figure is what the bus and the virtual servos cost;
* the same bare loop with the servos of the all-Python reference model
  (``ReferenceServo``): what the emulator cost before its servos' hot path moved to
  C, for the speed-up;
* the same loop through ``DxlClient`` on ``sim://``, as a Python controller runs it
  (the client's own work included), for reference.

The emulator's servos (``VirtualServo``) run their hot path in C whatever the bus
does: faults, echo, other baud rates and the physics world change nothing about which
code runs. A SYNC_WRITE of goals is handed to the C servos in one call when every
servo on its line is a C servo with an ID of its own (as here); otherwise servo by
servo. The bus's timing and fault code is Python; a READ on a quiet line with no
faults takes its short path (held until read, then ``Bus.master_receive`` hands the
frame to the C servo whole and the status packet straight to the master), the same
bytes at the same instants as the general path (``tests/sim/test_bus_fast_path.py``).

Printed: emulated seconds per CPU second of this process (real-time factor; the wall
clock figure is printed too, lower on a loaded machine), each against its goal (200x
for 5 servos, 100x for 18), and the exponent k of cost per tick ~ servos^k fitted over
the three sizes (goal: at most 1.2, i.e. close to linear).

    .venv/bin/python bench/bench_bus_scaling.py [--quick]
"""

from __future__ import annotations

import math
import os
import sys
import time

import numpy as np

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.formats import protocol
from snakebot.link.transport import DxlClient
from snakebot.sim.bus.bus import Bus
from snakebot.sim.options import SimOptions
from snakebot.sim.servo.reference import ReferenceServo

CONTROL_HZ = 100
SIZES = (5, 18, 50)
GOALS = {5: 200.0, 18: 100.0}
MAX_EXPONENT = 1.2
GOAL_ADDR, PRESENT_ADDR = 30, 36  # Goal Position, Present Position (2 bytes each)
REPLY_WAIT_S = 0.005


def goals_packet(ids: list[int], k: int) -> bytes:
    """The tick's SYNC_WRITE: a travelling sine over the servos."""
    t = k / CONTROL_HZ
    return protocol.sync_write(
        GOAL_ADDR,
        2,
        {
            sid: (512 + round(150 * math.sin(2 * math.pi * 0.5 * t + j))).to_bytes(2, "little")
            for j, sid in enumerate(ids)
        },
    )


def url(count: int) -> str:
    return f"sim://?ids={','.join(map(str, range(1, count + 1)))}&return_delay=0"


def reference_bus(count: int) -> Bus:
    """The bus of :func:`url` with ReferenceServo (the all-Python model) servos."""
    servos = [ReferenceServo(i) for i in range(1, count + 1)]
    for s in servos:
        s.set_register("Return Delay Time", 0)
    return Bus(servos)


def bare(count: int, ticks: int, reference: bool = False) -> tuple[float, float]:
    """(bus seconds per CPU second, per wall second) of the bare master's loop, on the
    emulator's servos or (``reference``) on the all-Python model's."""
    if reference:
        bus = reference_bus(count)
    else:
        bus = SimOptions.from_query(url(count).split("?", 1)[1]).build_bus()
    ids = [s.id for s in bus.servos]
    syncs = [goals_packet(ids, k) for k in range(ticks)]  # built before the clock starts
    reads = [protocol.read(sid, PRESENT_ADDR, 2) for sid in ids]
    status_len = len(protocol.status(1, 0, bytes(2)))
    cpu0, wall0 = time.process_time(), time.perf_counter()
    for k in range(ticks):
        bus.master_write(syncs[k])
        for packet in reads:
            bus.master_write(packet)
            if len(bus.master_receive(status_len, bus.now + REPLY_WAIT_S)) != status_len:
                raise SystemExit(f"no status packet on the emulated bus ({count} servos)")
        bus.run_until((k + 1) / CONTROL_HZ)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    return bus.now / cpu, bus.now / wall


def client(count: int, ticks: int) -> tuple[float, float]:
    """The same loop through DxlClient on sim://."""
    with DxlClient(url(count), latency_s=0.0) as c:
        bus = c.port.bus
        ids = [s.id for s in bus.servos]
        syncs = [goals_packet(ids, k) for k in range(ticks)]
        cpu0, wall0 = time.process_time(), time.perf_counter()
        for k in range(ticks):
            c.send(syncs[k])
            for sid in ids:
                c.read_u16(sid, PRESENT_ADDR)
            bus.run_until((k + 1) / CONTROL_HZ)
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
        return bus.now / cpu, bus.now / wall


def best(fn, count: int, ticks: int, rounds: int) -> tuple[float, float]:  # noqa: ANN001
    results = [fn(count, ticks) for _ in range(rounds)]
    return max(r[0] for r in results), max(r[1] for r in results)


def reference_bare(count: int, ticks: int) -> tuple[float, float]:
    """:func:`bare` on the all-Python reference servos."""
    return bare(count, ticks, reference=True)


def verdict(value: float, goal: float) -> str:
    return f"ratio {value / goal:.2f} of the goal {goal:.0f}x: {'met' if value >= goal else 'MISS'}"


def main() -> int:
    quick = "--quick" in sys.argv
    seconds = 1.0 if quick else 2.0
    rounds = 3
    print(
        f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} "
        "(the CPU-time figures suffer least from other processes)"
    )
    print(
        f"== closed loop at {CONTROL_HZ} Hz: one SYNC_WRITE + a READ of every servo per "
        f"tick, return delay 0, best of {rounds}"
    )
    per_tick = []
    for count in SIZES:
        ticks = int(seconds * CONTROL_HZ)
        cpu, wall = best(bare, count, ticks, rounds)
        r_cpu, r_wall = best(reference_bare, count, ticks, rounds)
        c_cpu, c_wall = best(client, count, ticks, rounds)
        per_tick.append(1.0 / (CONTROL_HZ * cpu))
        goal = GOALS.get(count)
        print(
            f"   {count:2d} servos: emulator {cpu:6.1f}x per CPU second ({wall:6.1f}x wall)"
            + (f", {verdict(cpu, goal)}" if goal else "")
        )
        print(
            f"             all-Python reference servos {r_cpu:6.1f}x per CPU second "
            f"({r_wall:6.1f}x wall): the C servos are {cpu / r_cpu:.2f}x as fast"
        )
        print(
            f"             through DxlClient on sim:// {c_cpu:6.1f}x per CPU second "
            f"({c_wall:6.1f}x wall; the client's share: {1 - c_cpu / cpu:.0%} of the time)"
        )
    k = float(np.polyfit(np.log(SIZES), np.log(per_tick), 1)[0])
    print(
        f"   cost per tick ~ servos^{k:.2f} over {SIZES} "
        f"(goal at most {MAX_EXPONENT}): {'met' if k <= MAX_EXPONENT else 'MISS'}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
