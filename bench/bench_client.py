"""Benchmark: snakebot's client against the wire-limited transaction rate.

A READ of two bytes at 1 Mbps with Return Delay Time 0 puts 8 bytes out and 8 bytes
back on the wire: 160 us, so no client can do more than 6250 READs a second. The device
here is this benchmark's own paced fake servo (``paced_servo.c``, compiled at the start
with the system's C compiler; a Python loop stands in without one): a separate process
on a pseudo-terminal that polls for the instruction in a tight loop (never sleeping, so
no wake-up delay), timestamps the read that completed it and releases the status packet
exactly 160 us later (the instruction's and the reply's wire time), so the device is
never the floor. Measured in the same run:

* the pseudo-terminal itself: a bare loop against the same fake servo answering at
  once. The kernel hands pty bytes over through a worker thread, so each direction
  costs some microseconds that a real wire would not: the round trip here caps any
  client at 160 us / (160 us + that round trip) of the wire;
* a bare client: os.write and os.read on the pty (blocking or polling, the faster),
  no serial library, no parsing: the best any client can do through the operating
  system here;
* snakebot's DxlClient (pyserial underneath), as an application uses it, and its own
  cost per READ beyond the bare loop's, in wall time and in CPU time (the CPU figures
  suffer least from other processes).

Each is printed as a fraction of the wire-limited rate (goal for DxlClient: at least
0.95), with what limits it: the pty (when even the bare loop falls short of the goal)
or the client. The device and the client need a core each: on a loaded machine the
figures drop.

    .venv/bin/python bench/bench_client.py [--quick]
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tty

from ptyfloor import bare_rate

from snakebot import protocol
from snakebot.transport import DxlClient
from snakebot.transport.timing import wire_time_s

BAUD = 1_000_000
SERVO_ID, ADDRESS, LENGTH = 1, 36, 2
REQUEST = protocol.read(SERVO_ID, ADDRESS, LENGTH)
REPLY = protocol.status(SERVO_ID, 0, bytes((0x00, 0x02)))
WIRE_S = wire_time_s(len(REQUEST) + len(REPLY), BAUD)
GOAL = 0.95


def serve(delay_s: float) -> None:
    """The fake servo: answer each READ ``delay_s`` (its wire time, or 0) after it arrives."""
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    print(os.ttyname(slave), flush=True)
    clock = time.perf_counter
    read, write = os.read, os.write
    size, request, reply = len(REQUEST), REQUEST, REPLY
    pending = b""
    while True:
        # Polls for the instruction in a tight loop rather than sleeping in the kernel:
        # a blocked reader is woken some microseconds after the bytes arrive, and that
        # delay would count against the client. It therefore needs a core of its own.
        try:
            pending += read(master, 64)
        except BlockingIOError:
            continue
        except OSError:
            return  # the benchmark has gone
        while (start := pending.find(request)) >= 0:  # every READ heard, in order
            release = clock() + delay_s
            pending = pending[start + size :]
            while clock() < release:
                pass
            write(master, reply)
        pending = pending[-(size - 1) :]  # what may begin the next READ


def client_rate(device: str, n: int) -> tuple[float, float]:
    """DxlClient's READs per second, and its CPU seconds per READ."""
    # a generous allowance: on a loaded machine the fake servo may be descheduled for a
    # while, which must cost a slow round, not a failure (the rate does not depend on it)
    with DxlClient(device, BAUD, latency_s=0.1, return_delay_us=0) as c:
        c.read_u16(SERVO_ID, ADDRESS)
        start, cpu = time.perf_counter(), time.process_time()
        for _ in range(n):
            c.read_u16(SERVO_ID, ADDRESS)
        return n / (time.perf_counter() - start), (time.process_time() - cpu) / n


def build_device(workdir: str) -> str | None:
    """The fake servo in C (``paced_servo.c``), compiled into ``workdir``: its path, or
    None if there is no C compiler (then the Python one in :func:`serve` stands in)."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        return None
    exe = os.path.join(workdir, "paced_servo")
    source = os.path.join(os.path.dirname(os.path.abspath(__file__)), "paced_servo.c")
    subprocess.run([cc, "-std=c99", "-O2", "-o", exe, source], check=True)
    return exe


def start_device(delay_s: float, exe: str | None) -> tuple[subprocess.Popen[str], str]:
    """A fake servo in its own process (``exe``: the C one) and the pty it answers on."""
    if exe is not None:
        command = [exe, REQUEST.hex(), REPLY.hex(), str(round(delay_s * 1e9))]
    else:
        command = [sys.executable, __file__, "--serve", repr(delay_s)]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    return proc, proc.stdout.readline().strip()


def bare_blocking(device: str, n: int) -> tuple[float, float]:
    """The bare loop waiting in select (as DxlClient does): its rate and CPU per READ."""
    cpu = time.process_time()
    rate = bare_rate(device, REQUEST, len(REPLY), n, False)
    return rate, (time.process_time() - cpu) / n


def best_bare(device: str, n: int) -> float:
    return max(bare_rate(device, REQUEST, len(REPLY), n, spin) for spin in (False, True))


def main() -> int:
    if "--serve" in sys.argv:
        serve(float(sys.argv[sys.argv.index("--serve") + 1]))
        return 0
    n = 1000 if "--quick" in sys.argv else 4000
    rounds = 5
    wire = 1 / WIRE_S
    print(
        f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} "
        "(the device and the client each need a core)"
    )
    instant = bare = ours = 0.0
    bare_cpu = ours_cpu = math.inf
    workdir = tempfile.TemporaryDirectory(prefix="bench_client_")
    exe = build_device(workdir.name)
    print(
        "== the fake servo: "
        + ("C (paced_servo.c)" if exe else "Python (no C compiler found; it may be the floor)")
    )
    for delay_s in (0.0, WIRE_S):  # one device at a time: each spins on a core
        proc, device = start_device(delay_s, exe)
        try:
            for _ in range(rounds):  # alternate, so load from other processes hits both alike
                if delay_s == 0.0:
                    instant = max(instant, best_bare(device, n // rounds))
                    continue
                bare = max(bare, best_bare(device, n // rounds))
                rate, cpu = client_rate(device, n // rounds)
                ours, ours_cpu = max(ours, rate), min(ours_cpu, cpu)
                bare_cpu = min(bare_cpu, bare_blocking(device, n // rounds)[1])
        finally:
            proc.kill()
            proc.wait()
    pty_us = 1e6 / instant
    hops_us = 1e6 / bare - WIRE_S * 1e6  # what the pty adds to a paced READ, at best
    print(
        f"== READ of {LENGTH} bytes at {BAUD // 1000} kbps, return delay 0, paced fake "
        f"servo; best of {rounds} rounds of {n // rounds}"
    )
    print(f"   wire limit:                 {wire:7.0f} /s")
    print(
        f"   the pty alone:              {pty_us:7.1f} us a round trip (bare loop, device "
        f"answering at once): caps any client at {WIRE_S / (WIRE_S + pty_us * 1e-6):.2f} "
        "of the wire"
    )
    print(
        f"   bare write/read loop:       {bare:7.0f} /s ({bare / wire:.2f} of the wire: the "
        f"pty adds {hops_us:.1f} us a READ; CPU {bare_cpu * 1e6:.1f} us a READ in select)"
    )
    print(
        f"   snakebot DxlClient:         {ours:7.0f} /s ({ours / wire:.2f} of the wire, "
        f"{ours / bare:.2f} of the bare loop, {1e6 / ours - 1e6 / bare:+.1f} us a READ "
        f"beyond it; CPU {ours_cpu * 1e6:.1f} us a READ)"
    )
    if ours / wire >= GOAL:
        verdict = "met"
    elif bare / wire < GOAL:
        verdict = (
            f"MISS, out of reach through this pty: even the bare loop, with no client "
            f"code, makes only {bare / wire:.2f} of the wire, the pty's two kernel hops "
            f"(and any wait for a core) adding {hops_us:.1f} us to the wire's "
            f"{WIRE_S * 1e6:.0f} us a READ "
            f"({GOAL} needs at most {WIRE_S * 1e6 * (1 / GOAL - 1):.1f} us)"
        )
    else:
        verdict = f"MISS, limited by the client: the bare loop makes {bare / wire:.2f} of the wire"
    print(f"   goal {GOAL} of the wire for DxlClient: {verdict}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
