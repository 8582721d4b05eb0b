"""Benchmark: snakebot's client against the wire-limited transaction rate.

A READ of two bytes at 1 Mbps with Return Delay Time 0 puts 8 bytes out and 8 bytes
back on the wire: 160 us, so no client can do more than 6250 READs a second, and the
goal (0.95 of that) leaves the client about 8.4 us a READ of its own.

The goal measurement: DxlClient against a paced device with nothing between the two,
:class:`PacedPort`, this benchmark's own port object inside the process (never shipped).
Its ``write`` timestamps the instruction as it begins; its ``read`` hands the whole
status packet over exactly when the reply's last byte would arrive on the wire, 160 us
after that, spinning until then (a wait in the kernel would wake late). DxlClient takes
it as an application hands in any port object of its own (pyserial's interface, the path
``sim://`` takes too), so every line of the client's transaction runs as in use. This is
the least favourable fair reference, the wire itself: a real servo cannot answer sooner,
and whatever the client does between a reply and its next instruction shows as a
shortfall. The device's own few Python calls count against the client as well; the
device alone (a bare write/read loop on it) is measured to show that it is not the floor.
A READ's time is the median of READs timed one by one, the least of a few rounds: the
device spins in this process, so a READ during which another process had the core would
count that process's time (on an idle machine the median and the mean agree). The CPU
per READ is measured against the same device answering at once: the client's is the
whole less the bare loop's.

The sustained rate, beside it: :data:`SUSTAINED_READS` READs back to back against the
same paced device, as a program polling a servo makes them, so whatever a READ leaves
behind for the next (garbage, a growing cache, a slow path taken now and then) counts.
Its time is the run's CPU time (the device spins through each wire time, so an
undisturbed run takes as much CPU as wall time, and a run that another process
interrupts is not charged for it; nor, though, for the part of a wire time it spent
interrupted, so on a loaded machine the figure leans high), the median of rounds
interleaved with the per-READ ones; the wall-clock rate is printed beside it (on an idle
machine the two agree). Goal: :data:`SUSTAINED_GOAL` of the wire.

What the operating system adds, measured in the same run and printed second: the same
device pacing in C (``paced_servo.c``, compiled at the start with the system's C
compiler; a Python loop stands in without one) as a separate process on a
pseudo-terminal, polling for the instruction in a tight loop:

* the pseudo-terminal itself: a bare loop against that device answering at once. The
  kernel hands pty bytes over through a worker thread, so each direction costs some
  microseconds that a real wire would not: the round trip here caps any client at
  160 us / (160 us + that round trip) of the wire;
* a bare client: os.write and os.read on the pty, no serial library, no parsing, both
  waiting in select and polling: the faster is the best any client can do through the
  operating system here;
* DxlClient through the pty (pyserial's descriptor underneath), as an application uses
  it, and its own cost per READ beyond the bare loop that waits in select as it does.

The paced devices spin: each needs a core, and on a loaded machine the figures drop
(the CPU figures suffer least).

    .venv/bin/python bench/bench_client.py [--quick]
"""

from __future__ import annotations

import functools
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import tty
from dataclasses import dataclass

import serial
from ptyfloor import bare_rate

from snakebot.formats import protocol
from snakebot.link.transport import DxlClient
from snakebot.link.transport.timing import wire_time_s

BAUD = 1_000_000
SERVO_ID, ADDRESS, LENGTH = 1, 36, 2
REQUEST = protocol.read(SERVO_ID, ADDRESS, LENGTH)
REPLY = protocol.status(SERVO_ID, 0, bytes((0x00, 0x02)))
WIRE_S = wire_time_s(len(REQUEST) + len(REPLY), BAUD)
GOAL = 0.95
SUSTAINED_READS = 3000
SUSTAINED_GOAL = 0.9


class PacedPort(serial.SerialBase):
    """The paced device inside this process, as a pyserial port: a ``write`` of the
    instruction timestamps it, and ``read`` returns the reply ``delay_s`` after that
    (the wire time, or 0: at once), spinning until then; anything else written is
    heard and not answered, as a servo ignores what is not addressed to it."""

    def __init__(self, delay_s: float) -> None:
        super().__init__(baudrate=BAUD)  # no port name: nothing is opened
        self.is_open = True
        self._delay_s = delay_s
        self._release = 0.0  # when the reply's last byte is in
        self._rest = b""  # the reply's bytes not read yet

    def _reconfigure_port(self, force_update: bool = False) -> None:
        """Nothing to set: the device keeps the wire's pace by itself."""

    def open(self) -> None:
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    @property
    def in_waiting(self) -> int:
        return len(self._rest) if time.perf_counter() >= self._release else 0

    def reset_input_buffer(self) -> None:
        if time.perf_counter() >= self._release:  # only bytes that have arrived
            self._rest = b""

    def write(self, data: bytes) -> int:
        if data == REQUEST:
            self._release = time.perf_counter() + self._delay_s
            self._rest = REPLY
        return len(data)

    def read(self, size: int = 1) -> bytes:
        clock = time.perf_counter
        # with nothing on its way, wait out the timeout as a port would
        until = self._release if self._rest else clock() + (self._timeout or 0.0)
        while clock() < until:
            pass
        data, self._rest = self._rest[:size], self._rest[size:]
        return data


def in_process(delay_s: float, n: int, client: bool) -> tuple[float, float]:
    """Seconds a READ takes against :class:`PacedPort` answering after ``delay_s`` (the
    median of ``n``, each timed alone: a READ during which another process had the core
    would count that process's time), and CPU seconds per READ: of DxlClient
    (``client``), else of a bare write/read loop on the port (the device alone)."""
    port = PacedPort(delay_s)
    if client:
        # a generous allowance: a READ descheduled for a while must be slow, not fail
        bus = DxlClient(port, return_delay_us=0, latency_s=0.1)
        read = functools.partial(bus.read_u16, SERVO_ID, ADDRESS)
    else:
        port.timeout = 0.1
        flush, write, read_bytes = port.reset_input_buffer, port.write, port.read
        size = len(REPLY)

        def read() -> None:
            flush()
            write(REQUEST)
            read_bytes(size)

    read()  # the client settles echo detection (this device does not echo)
    clock = time.perf_counter
    times = [0.0] * n
    cpu = time.process_time()
    last = clock()
    for i in range(n):
        read()
        times[i] = (now := clock()) - last
        last = now
    return statistics.median(times), (time.process_time() - cpu) / n


def sustained(n: int) -> tuple[float, float]:
    """DxlClient's READs a second over ``n`` READs back to back against the paced device:
    by the run's CPU time, and by its wall time."""
    port = PacedPort(WIRE_S)
    bus = DxlClient(port, return_delay_us=0, latency_s=0.1)
    bus.read_u16(SERVO_ID, ADDRESS)  # echo detection settled
    read = functools.partial(bus.read_u16, SERVO_ID, ADDRESS)
    start, cpu = time.perf_counter(), time.process_time()
    for _ in range(n):
        read()
    return n / (time.process_time() - cpu), n / (time.perf_counter() - start)


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


def bare_rates(device: str, n: int) -> tuple[float, float]:
    """The bare loop's rates on ``device``: waiting in select (as DxlClient does), and
    polling (as dynamixel-sdk does)."""
    return (
        bare_rate(device, REQUEST, len(REPLY), n, False),
        bare_rate(device, REQUEST, len(REPLY), n, True),
    )


@dataclass
class InProcess:
    """Against the paced device in this process: DxlClient's and the bare loop's seconds
    a READ (median, the least of the rounds), their least CPU per READ against the device
    answering at once, and DxlClient's sustained rates (median of the rounds)."""

    read_s: float
    alone_s: float
    ours_cpu: float
    alone_cpu: float
    sustained_cpu: float
    sustained_wall: float


def measure_in_process(n: int, rounds: int) -> InProcess:
    ours = alone = ours_cpu = alone_cpu = math.inf
    runs: list[tuple[float, float]] = []
    for _ in range(rounds):  # alternate, so load from other processes hits all alike
        ours = min(ours, in_process(WIRE_S, n, True)[0])
        alone = min(alone, in_process(WIRE_S, n, False)[0])
        ours_cpu = min(ours_cpu, in_process(0.0, 4 * n, True)[1])
        alone_cpu = min(alone_cpu, in_process(0.0, 4 * n, False)[1])
        runs.append(sustained(SUSTAINED_READS))
    return InProcess(
        ours,
        alone,
        ours_cpu,
        alone_cpu,
        statistics.median(r[0] for r in runs),
        statistics.median(r[1] for r in runs),
    )


@dataclass
class PtyFigures:
    """What a pty adds: the best of the rounds measured through it."""

    round_trip_s: float = math.inf  # the pty alone: a bare loop, the device answering at once
    bare: float = 0.0  # a bare write/read loop's READs a second, the faster way of waiting
    bare_select: float = 0.0  # the same waiting in select, as DxlClient does
    client: float = 0.0  # DxlClient's READs a second
    client_cpu: float = math.inf  # DxlClient's CPU seconds a READ, system calls included
    device_in_c: bool = True  # False: the Python stand-in, which may be the floor


def measure_pty(n: int, rounds: int) -> PtyFigures:
    """Through a pty to the paced device in its own process."""
    got = PtyFigures()
    with tempfile.TemporaryDirectory(prefix="bench_client_") as workdir:
        exe = build_device(workdir)
        got.device_in_c = exe is not None
        for delay_s in (0.0, WIRE_S):  # one device at a time: each spins on a core
            proc, device = start_device(delay_s, exe)
            try:
                for _ in range(rounds):  # alternate, as above
                    if delay_s == 0.0:
                        got.round_trip_s = min(got.round_trip_s, 1 / max(bare_rates(device, n)))
                        continue
                    select_rate, spin_rate = bare_rates(device, n)
                    got.bare_select = max(got.bare_select, select_rate)
                    got.bare = max(got.bare, select_rate, spin_rate)
                    rate, cpu = client_rate(device, n)
                    got.client, got.client_cpu = max(got.client, rate), min(got.client_cpu, cpu)
            finally:
                proc.kill()
                proc.wait()
    return got


def main() -> int:
    if "--serve" in sys.argv:
        serve(float(sys.argv[sys.argv.index("--serve") + 1]))
        return 0
    n = 1000 if "--quick" in sys.argv else 4000
    rounds = 5
    wire = 1 / WIRE_S
    print(
        f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} "
        "(each paced device spins on a core)"
    )
    print(
        f"== READ of {LENGTH} bytes at {BAUD // 1000} kbps, return delay 0: the wire allows "
        f"{wire:.0f} /s ({WIRE_S * 1e6:.0f} us a READ); best of {rounds} rounds of "
        f"{n // rounds}"
    )
    got = measure_in_process(n // rounds, rounds)
    read_s, alone_s, ours_cpu, alone_cpu = got.read_s, got.alone_s, got.ours_cpu, got.alone_cpu
    ours, alone = 1 / read_s, 1 / alone_s
    print(
        f"   DxlClient, paced device in process: {ours:7.0f} /s = {ours / wire:.3f} of the "
        f"wire, {(read_s - WIRE_S) * 1e6:.1f} us a READ beyond it (the device alone, a "
        f"bare write/read loop on it: {alone / wire:.3f}); CPU a READ {ours_cpu * 1e6:.1f} "
        f"us, the client's {(ours_cpu - alone_cpu) * 1e6:.1f} us and the device's "
        f"{alone_cpu * 1e6:.1f} us"
    )
    sustained_ok = got.sustained_cpu / wire >= SUSTAINED_GOAL
    print(
        f"   DxlClient sustained, {SUSTAINED_READS} READs back to back (median of {rounds}): "
        f"{got.sustained_cpu:7.0f} /s = {got.sustained_cpu / wire:.3f} of the wire by CPU "
        f"time, {got.sustained_wall / wire:.3f} by the wall clock; goal {SUSTAINED_GOAL}: "
        f"{'met' if sustained_ok else 'MISS'}"
    )
    pty = measure_pty(n // rounds, rounds)
    device = "C" if pty.device_in_c else "Python, no C compiler found: it may be the floor"
    print(
        f"   through a pty (the device in {device}, its own process): the pty alone "
        f"{pty.round_trip_s * 1e6:.1f} us a round trip; bare write/read loop "
        f"{pty.bare / wire:.2f} of the wire (the kernel adds "
        f"{1e6 / pty.bare - WIRE_S * 1e6:.1f} us a READ), {pty.bare_select / wire:.2f} "
        f"waiting in select; DxlClient {pty.client / wire:.2f} of the wire "
        f"({1e6 / pty.client - 1e6 / pty.bare_select:+.1f} us a READ beyond the loop in "
        f"select; CPU {pty.client_cpu * 1e6:.1f} us a READ, system calls included)"
    )
    if ours / wire >= GOAL:
        verdict = "met"
    elif alone / wire < GOAL:
        verdict = f"MISS, the device is the floor here: alone it makes {alone / wire:.3f}"
    else:
        verdict = (
            f"MISS, limited by the client: {(read_s - WIRE_S) * 1e6:.1f} us a READ beyond "
            f"the wire, {GOAL} allows {WIRE_S * 1e6 * (1 / GOAL - 1):.1f}"
        )
    print(f"   goal {GOAL} of the wire for DxlClient against the paced device: {verdict}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
