"""Benchmarks of the emulated Dynamixel bus, each a ratio measured in this run.

1. Real-time factor of the emulated 5-link robot (snake5: four AX-12A on one bus) with
   the host as bus master at a 100 Hz control loop, in process (sim://): bus seconds
   emulated per wall second and per CPU second. Goal: at least 200x (the closed loop at
   several roster sizes is bench_bus_scaling.py's). Two loads: goals only (one SYNC_WRITE
   per tick, as when a gait is played straight onto the servos) and goals plus a READ
   of every servo's present position per tick; for the second, what each layer adds to
   a tick (the loop's own goals, their SYNC_WRITE through the client and the bus; per
   READ: the frame handed to the bus and its status packet taken as the sim:// port
   takes it, the port itself, the client), each measured with the same loop.
2. The rate the pseudo-terminal transport allows: READ transactions per second through
   `snakebot sim bus --pty` (a separate process, as a user runs it), against the rate
   the wire itself allows at 1 Mbps with Return Delay Time 0 (16 bytes = 160 us).
3. snakebot's client against ROBOTIS's dynamixel-sdk on the same pty, same run:
   transactions per second of each (goal: snakebot at least 2x). Also measured in the
   same run, on the same pty: the server's floor, a bare loop of os.write and os.read
   with no serial library and no parsing, which a client can at best match. A client
   near the floor is bound by the server (whose bus clock follows the wall clock), not
   by its own code.

    .venv/bin/python bench/bench_sim.py [--quick]
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time

from ptyfloor import bare_rate

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.facts import devices
from snakebot.formats import protocol
from snakebot.link.transport import DxlClient

AX12 = devices.ax12()
GOAL = AX12.register("Goal Position")
PRESENT = AX12.register("Present Position")
CENTRE = AX12.require_position().centre
CONTROL_HZ = 100
WIRE_READ_S = 16 * 10 / 1_000_000  # READ of 2 bytes: 8 + 8 bytes at 10 us


def rtf(seconds: float, reads: bool | str) -> tuple[float, float]:
    """Bus seconds per wall second and per CPU second of this process, for a
    ``seconds``-long 100 Hz loop driving snake5's joints along a travelling sine.

    ``reads``: False for goals only; True (or "client") for a READ of every servo's
    position each tick through the client; "port" for the same READ frames written and
    read on the sim:// port directly, "bus" for them handed to the bus directly and the
    status packets taken as the port's timed read takes them (``Bus.master_receive``);
    "goals" for the goals worked out and nothing sent (what each layer adds: see
    ``where_the_time_goes``)."""
    with DxlClient("sim://?robot=snake5&return_delay=0", latency_s=0.0) as c:
        bus = c.port.bus
        port = c.port
        ids = [s.id for s in bus.servos]
        frames = [protocol.read(sid, PRESENT.address, PRESENT.size) for sid in ids]
        reply_len = len(protocol.status(ids[0], 0, bytes(PRESENT.size)))
        port.timeout = 0.01  # "port": a READ's whole answer, however long the wire is busy
        ticks = int(seconds * CONTROL_HZ)
        wall0, cpu0 = time.perf_counter(), time.process_time()
        for k in range(ticks):
            t = k / CONTROL_HZ
            goals = {
                sid: (CENTRE + round(150 * math.sin(2 * math.pi * 0.5 * t + j * math.pi / 2)))
                for j, sid in enumerate(ids)
            }
            blocks = {sid: GOAL.encode(g) for sid, g in goals.items()}
            if reads != "goals":
                c.sync_write(GOAL.address, GOAL.size, blocks)
            if reads is True or reads == "client":
                for sid in ids:
                    c.read_u16(sid, PRESENT.address)
            elif reads == "port":
                for frame in frames:
                    port.reset_input_buffer()
                    port.write(frame)
                    port.read(reply_len)
            elif reads == "bus":
                for frame in frames:
                    bus.master_flush_input()
                    bus.master_write(frame)
                    bus.master_receive(reply_len, bus.now + port.timeout)
            bus.run_until((k + 1) / CONTROL_HZ)
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        return bus.now / wall, bus.now / cpu


def best_rtf(seconds: float, reads: bool | str, rounds: int = 3) -> tuple[float, float]:
    results = [rtf(seconds, reads) for _ in range(rounds)]
    return max(r[0] for r in results), max(r[1] for r in results)


def where_the_time_goes(seconds: float) -> None:
    """CPU time of one tick of the closed loop, layer by layer (each the best of 3 runs
    of the same loop, in this run): the loop's own goals, then their SYNC_WRITE (through
    the client, the port and the bus), then the 4 READs handed to the bus, through the
    sim:// port, through the client. Prints what each layer adds (per READ for the
    READs) and the most the loop could reach if the bus and the port cost nothing (the
    client's own part and the rest of the tick as measured)."""
    tick_us = {
        layer: 1e6 / CONTROL_HZ / best_rtf(seconds, layer)[1]
        for layer in ("goals", False, "bus", "port", "client")
    }
    reads = 4
    goals = tick_us["goals"]
    sync_write = tick_us[False] - goals
    bus = (tick_us["bus"] - tick_us[False]) / reads
    port = (tick_us["port"] - tick_us["bus"]) / reads
    client = (tick_us["client"] - tick_us["port"]) / reads
    floor = 1e6 / CONTROL_HZ / (tick_us[False] + reads * client)
    budget = 1e6 / CONTROL_HZ / 200
    print(
        f"   where the time goes, per tick: the loop's goals {goals:.1f} us, their SYNC_WRITE "
        f"(client, port, bus) {sync_write:.1f} us; per READ: bus {bus:.1f} us, sim:// port "
        f"{port:.1f} us, client {client:.1f} us (200 x allows {budget:.0f} us a tick; with "
        f"the bus and the port free, the client and the rest would still allow at most "
        f"{floor:.0f} x)"
    )


def start_server() -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "snakebot",
            "sim",
            "bus",
            "--robot",
            "snake5",
            "--pty",
            "--return-delay",
            "0",
            "--json",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    return proc, json.loads(proc.stdout.readline())["device"]


def snakebot_rate(device: str, n: int) -> float:
    # a generous allowance: on a loaded machine the server (whose bus clock follows the
    # wall clock) may be descheduled for a while, which must cost a slow round, not a
    # failure (the rate does not depend on it)
    with DxlClient(device, latency_s=0.1) as c:
        c.read_u16(10, PRESENT.address)
        start = time.perf_counter()
        for _ in range(n):
            c.read_u16(10, PRESENT.address)
        return n / (time.perf_counter() - start)


def floor_rate(device: str, n: int, spin: bool) -> float:
    """READs per second of a bare write/read loop on the pty (ptyfloor.bare_rate)."""
    return bare_rate(device, protocol.read(10, PRESENT.address, PRESENT.size), 8, n, spin)


def sdk_rate(device: str, n: int) -> float:
    import dynamixel_sdk as sdk

    port = sdk.PortHandler(device)
    handler = sdk.PacketHandler(1.0)
    if not (port.openPort() and port.setBaudRate(1_000_000)):
        raise RuntimeError(f"dynamixel-sdk cannot open {device}")
    try:
        handler.read2ByteTxRx(port, 10, PRESENT.address)
        failures = 0
        start = time.perf_counter()
        for _ in range(n):
            _, result, _ = handler.read2ByteTxRx(port, 10, PRESENT.address)
            failures += result != sdk.COMM_SUCCESS
        rate = n / (time.perf_counter() - start)
    finally:
        port.closePort()
    if failures:
        print(f"   (dynamixel-sdk: {failures} of {n} transactions failed)")
    return rate


def main() -> int:
    quick = "--quick" in sys.argv
    seconds = 5 if quick else 20
    n = 300 if quick else 1000
    rounds = 5
    print(
        f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} "
        "(wall-clock figures suffer on a loaded machine; CPU-time ones much less)"
    )

    print(
        f"== 1. snake5 at {CONTROL_HZ} Hz, host as master, in process "
        f"({seconds} s of bus time, best of 3)"
    )
    for label, reads, span in (
        ("goals only (SYNC_WRITE per tick):  ", False, seconds),
        ("goals + 4 position READs per tick: ", True, seconds / 5),
    ):
        wall, cpu = best_rtf(span, reads)
        print(
            f"   {label} {wall:6.1f} x real time by the wall clock, {cpu:6.1f} x per CPU "
            f"second (goal 200 x: ratios {wall / 200:.2f}, {cpu / 200:.2f}; "
            f"{'met' if cpu >= 200 else 'MISS'} per CPU second)"
        )
    where_the_time_goes(seconds / 5)

    print(
        f"== 2 and 3. READ transactions over a pty served by `snakebot sim bus` "
        f"({n} per client, in {rounds} alternating rounds, best round)"
    )
    proc, device = start_server()
    try:
        with DxlClient("sim://?robot=snake5&return_delay=0", latency_s=0.0) as c:
            start = time.perf_counter()
            for _ in range(n):
                c.read_u16(10, PRESENT.address)
            in_process = n / (time.perf_counter() - start)
        ours = theirs = floor = 0.0
        for _ in range(rounds):
            for spin in (False, True):
                floor = max(floor, floor_rate(device, n // rounds, spin))
            ours = max(ours, snakebot_rate(device, n // rounds))
            theirs = max(theirs, sdk_rate(device, n // rounds))
        wire = 1 / WIRE_READ_S
        print(f"   wire limit at 1 Mbps, delay 0:        {wire:7.0f} /s")
        print(
            f"   snakebot client, sim:// in process:   {in_process:7.0f} /s "
            f"({in_process / wire:.2f} x the wire: in process the bus is not tied to the clock)"
        )
        print(
            f"   the server's floor (bare loop, faster of select and polling): {floor:7.0f} /s "
            f"({floor / wire:.2f} x the wire)"
        )
        print(
            f"   snakebot client over the pty:         {ours:7.0f} /s "
            f"({ours / wire:.2f} x the wire, {ours / floor:.2f} x the floor)"
        )
        print(
            f"   dynamixel-sdk over the same pty:      {theirs:7.0f} /s "
            f"({theirs / wire:.2f} x the wire, {theirs / floor:.2f} x the floor)"
        )
        print(
            f"   snakebot / dynamixel-sdk:             {ours / theirs:7.2f} x "
            f"(goal 2 x: {'met' if ours / theirs >= 2 else 'MISS'})"
        )
        print(
            f"   (a client can at best match the floor: over this server, at most "
            f"{floor / theirs:.2f} x dynamixel-sdk)"
        )
    finally:
        proc.send_signal(2)
        proc.wait(timeout=10)
        assert proc.stdout is not None
        proc.stdout.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
