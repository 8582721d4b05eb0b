"""Benchmark: snakebot's client against the wire-limited transaction rate.

A READ of two bytes at 1 Mbps with Return Delay Time 0 puts 8 bytes out and 8 bytes
back on the wire: 160 us, so no client can do more than 6250 READs a second. The device
here is this benchmark's own paced fake servo: a separate process on a pseudo-terminal
that polls for the instruction in a tight loop and releases the status packet exactly
160 us after the instruction reached it (the instruction's and the reply's wire time),
so the device is never the floor. Measured in the same run:

* a bare client: os.write and os.read on the pty (blocking or polling, the faster),
  no serial library, no parsing: the best any client can do through the operating
  system here;
* snakebot's DxlClient (pyserial underneath), as an application uses it.

Each is printed as a fraction of the wire-limited rate (goal for DxlClient: at least
0.95). The two processes need a core each: on a loaded machine the figures drop.

    .venv/bin/python bench/bench_client.py [--quick]
"""

from __future__ import annotations

import os
import subprocess
import sys
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


def serve() -> None:
    """The paced fake servo: answer each READ 160 us (its wire time) after it arrives."""
    master, slave = os.openpty()
    tty.setraw(slave)
    print(os.ttyname(slave), flush=True)
    clock = time.perf_counter
    pending = b""
    while True:
        # Blocks for the instruction (so that it leaves the core to the client while it
        # waits) and spins only for the reply's release time, which it must not miss.
        try:
            pending += os.read(master, 64)
        except OSError:
            return  # the benchmark has gone
        while (start := pending.find(REQUEST)) >= 0:  # every READ heard, in order
            release = clock() + WIRE_S
            pending = pending[start + len(REQUEST) :]
            while clock() < release:
                pass
            os.write(master, REPLY)
        pending = pending[-(len(REQUEST) - 1) :]  # what may begin the next READ


def client_rate(device: str, n: int) -> float:
    # a generous allowance: on a loaded machine the fake servo may be descheduled for a
    # while, which must cost a slow round, not a failure (the rate does not depend on it)
    with DxlClient(device, BAUD, latency_s=0.1, return_delay_us=0) as c:
        c.read_u16(SERVO_ID, ADDRESS)
        start = time.perf_counter()
        for _ in range(n):
            c.read_u16(SERVO_ID, ADDRESS)
        return n / (time.perf_counter() - start)


def main() -> int:
    if "--serve" in sys.argv:
        serve()
        return 0
    n = 1000 if "--quick" in sys.argv else 4000
    rounds = 5
    wire = 1 / WIRE_S
    print(
        f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} "
        "(the device and the client each need a core)"
    )
    proc = subprocess.Popen(
        [sys.executable, __file__, "--serve"], stdout=subprocess.PIPE, text=True
    )
    try:
        assert proc.stdout is not None
        device = proc.stdout.readline().strip()
        bare = ours = 0.0
        for _ in range(rounds):  # alternate, so load from other processes hits both alike
            for spin in (False, True):
                bare = max(bare, bare_rate(device, REQUEST, len(REPLY), n // rounds, spin))
            ours = max(ours, client_rate(device, n // rounds))
    finally:
        proc.kill()
        proc.wait()
    print(
        f"== READ of {LENGTH} bytes at {BAUD // 1000} kbps, return delay 0, paced fake "
        f"servo; best of {rounds} rounds of {n // rounds}"
    )
    print(f"   wire limit:                 {wire:7.0f} /s")
    print(f"   bare write/read loop:       {bare:7.0f} /s ({bare / wire:.2f} of the wire)")
    print(
        f"   snakebot DxlClient:         {ours:7.0f} /s ({ours / wire:.2f} of the wire, "
        f"{ours / bare:.2f} of the bare loop; goal {GOAL} of the wire: "
        f"{'met' if ours / wire >= GOAL else 'MISS'})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
