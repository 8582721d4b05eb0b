"""Benchmark: `snakebot bus scan` of all 254 IDs against the physical limit, at its
defaults and on every kind of line, against dynamixel-sdk's ping loop at equal settings,
and over every tabulated rate.

Two buses: the in-process emulator (``sim://``, whose silent reads still take their time
on the wall clock) and the emulator's paced pseudo-terminal (`snakebot sim bus --pty`, in
its own process, as a real bus is outside the host's): virtual AX-12As that answer in real
time with the longest Return Delay Time (508 us), so the timing of a silent ID is what a
real bus gives. Rounds alternate between the scans, so load from other processes hits
each alike; the lines give the median of the rounds (and the best) beside a limit
computed for the same settings:

* the physical limit at 1 Mbps: per ID, a PING and a status packet on the wire (10 bits a
  byte), the return delay and the adapter's latency (about 0.16 s with none): the goal is
  a default scan (the latency the adapter reports, the scan's own margin, every silent ID
  PINGed a second time at the end) within 3x of it, on ``sim://`` also under 0.5 s; on
  the pty also with a 1 ms latency timer (``SNAKEBOT_LATENCY_MS=1``, what a lowered FTDI
  adapter reports), against its limit with that latency;
* dynamixel-sdk's ``ping`` over every ID, and snakebot's scan waiting for a silent ID
  exactly as long as the SDK's formula waits for a reply (its latency timer set to 0 for
  both), and told, as the SDK assumes, that the line has no echo (otherwise snakebot
  spends one reply timeout asking the line first): snakebot PINGs every silent ID twice,
  the SDK once, so the goal is no more than twice the SDK's time. What is compared is
  that time; what each finds is shown beside it, in how many rounds each found every
  servo, and is not the goal: the SDK flushes the line before each PING and gives it
  that one wait, so a reply the pty delivers later (its server and the kernel's tty
  work scheduled late, beside other work on the machine) is lost, and the servo with
  it, where snakebot takes a reply in any later window of the scan;
* a default scan of every tabulated rate (``--bauds all``), beside that list's physical
  limit: per ID the least a scan must wait, a PING, the return delay and the first byte
  of a reply (the rest of the status only where a servo answers). The time above the
  limit is split into the second PINGs, the margins a reliable scan keeps (the quiet
  pause before each further rate, which lets servos drop a frame begun by the last
  rate's garbage, and the host margin of every silent ID) and the rest, the host's own.

A scan that misses a servo is marked MISS whatever its time.

    .venv/bin/python bench/bench_scan.py
"""

from __future__ import annotations

import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import dynamixel_sdk
import dynamixel_sdk.port_handler as sdk_port

from snakebot.formats import protocol, register_values
from snakebot.link.bus import scan as bus_scan
from snakebot.link.transport import open_port, settings
from snakebot.link.transport.timing import wire_time_s

BAUD = 1_000_000
IDS = range(0, protocol.MAX_ID + 1)
SERVOS = (1, 2, 3)
RETURN_DELAY_US = bus_scan.longest_return_delay_us()  # the servos are set to it
PHYSICAL_GOAL = 3.0
SIM_GOAL_S = 0.5
SDK_GOAL = 2.0
LOWERED_LATENCY_MS = 1.0
ROUNDS = 5
ALL_RATES_ROUNDS = 2
SERVER_START_S = 30.0
PING = protocol.ping(1)
STATUS_LEN = len(protocol.status(1, 0, b""))
SIM_URL = "sim://?ids=" + ",".join(map(str, SERVOS)) + f"&return_delay={RETURN_DELAY_US:g}"

Run = tuple[float, list[int]]


def physical_s(baud: int, latency_ms: float = 0.0) -> float:
    """The issue's limit at one rate: every ID's PING, status packet, return delay and
    the adapter's latency."""
    per_id = wire_time_s(len(PING) + STATUS_LEN, baud) + RETURN_DELAY_US * 1e-6
    return len(IDS) * (per_id + latency_ms * 1e-3)


def scan_floor_s(bauds: list[int]) -> float:
    """The least a scan of ``bauds`` can take: at each rate every ID's PING, the return
    delay and a status packet's first byte; the rest of the status where a servo is."""
    silent = sum(len(IDS) * (wire_time_s(len(PING) + 1, b) + RETURN_DELAY_US * 1e-6) for b in bauds)
    return silent + len(SERVOS) * wire_time_s(STATUS_LEN - 1, BAUD)


def sdk_timeout_ms(baud: int) -> float:
    """dynamixel-sdk's wait for a PING's status packet (PortHandler.setPacketTimeout)."""
    return wire_time_s(STATUS_LEN, baud) * 1e3 + sdk_port.LATENCY_TIMER * 2.0 + 2.0


def equal_margin_ms(baud: int) -> float:
    """The host margin that makes snakebot's wait for a silent ID the SDK's reply timeout."""
    unpadded = wire_time_s(len(PING) + 1, baud) + RETURN_DELAY_US * 1e-6
    return sdk_timeout_ms(baud) - unpadded * 1e3


@contextmanager
def served_bus() -> Iterator[str]:
    """`snakebot sim bus` on a pty in a process of its own; yields the device."""
    with tempfile.TemporaryDirectory() as tmp:
        link = Path(tmp) / "ttyDXL"
        ids = ",".join(map(str, SERVOS))
        command = [sys.executable, "-m", "snakebot", "sim", "bus", "--pty", "--ids", ids]
        command += ["--return-delay", f"{RETURN_DELAY_US:g}", "--link", str(link)]
        server = subprocess.Popen(command, stdout=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + SERVER_START_S
            while not link.exists():
                if server.poll() is not None or time.monotonic() > deadline:
                    raise SystemExit("error: `snakebot sim bus --pty` did not start")
                time.sleep(0.05)
            yield str(link)
        finally:
            server.send_signal(signal.SIGINT)
            server.wait()


def snakebot_scan(
    device: str,
    bauds: list[int],
    *,
    latency_ms: float | None = None,
    margin_ms: float | None = None,
    echo: str = "auto",
) -> Run:
    """One scan, timed; None keeps a setting at its default (what the adapter reports,
    the scan's own margin)."""
    for name, value in ((settings.ENV_LATENCY_MS, latency_ms), (settings.ENV_MARGIN_MS, margin_ms)):
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = f"{value}"
    os.environ[settings.ENV_ECHO] = echo
    with open_port(device, bauds[0], timeout=0) as link:
        start = time.perf_counter()
        found = bus_scan.scan(link, IDS, bauds)
        return time.perf_counter() - start, [s.id for s in found]


def sdk_scan(device: str) -> Run:
    port = dynamixel_sdk.PortHandler(device)
    port.openPort()
    port.setBaudRate(BAUD)
    handler = dynamixel_sdk.PacketHandler(1.0)
    found = []
    start = time.perf_counter()
    for servo_id in IDS:
        _, result, _ = handler.ping(port, servo_id)
        if result == dynamixel_sdk.COMM_SUCCESS:
            found.append(servo_id)
    elapsed = time.perf_counter() - start
    port.closePort()
    return elapsed, found


def per_id_ms(seconds: float) -> float:
    return seconds / len(IDS) * 1e3


def median(runs: list[Run]) -> tuple[float, float]:
    """The median and the best time of ``runs``."""
    times = [r[0] for r in runs]
    return statistics.median(times), min(times)


def found_all(runs: list[Run]) -> str:
    """In how many of ``runs`` every servo was found, and what the worst one found."""
    whole = sum(r[1] == list(SERVOS) for r in runs)
    worst = min((r[1] for r in runs), key=len)
    tail = "" if whole == len(runs) else f", the worst found {worst}"
    return f"found every servo in {whole} of {len(runs)} rounds{tail}"


def verdict(ok: bool, runs: list[Run]) -> str:
    if any(r[1] != list(SERVOS) for r in runs):
        return f"MISS ({found_all(runs)})"
    return "met" if ok else "MISS"


def against_limit(label: str, runs: list[Run], limit: float, goal_s: float | None = None) -> None:
    took, fastest = median(runs)
    ratio = took / limit
    ok = ratio <= PHYSICAL_GOAL and (goal_s is None or took < goal_s)
    goal = f"goal {PHYSICAL_GOAL:g}x" + (f" and < {goal_s:g} s" if goal_s else "")
    print(
        f"   {label:<34}{took:6.3f} s (best {fastest:.3f}; {ratio:.2f}x its limit "
        f"{limit:.3f} s; {goal}: {verdict(ok, runs)})"
    )


def main() -> int:
    sdk_port.LATENCY_TIMER = 0  # no USB adapter here: both sides wait without it
    limit = physical_s(BAUD)
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(f"== 254 IDs at {BAUD} bps, servos {SERVOS}, Return Delay {RETURN_DELAY_US:g} us")
    print(
        f"   median of {ROUNDS} interleaved rounds; scan margin {bus_scan.SCAN_MARGIN_S * 1e3:g} ms"
    )
    print(f"   physical limit, no latency:        {limit:6.3f} s")
    runs: dict[str, list[Run]] = {k: [] for k in ("sim", "pty", "pty1", "sdk", "equal")}
    with served_bus() as device:
        for _ in range(ROUNDS):  # alternate, so load from other processes hits each alike
            runs["sim"].append(snakebot_scan(SIM_URL, [BAUD]))
            runs["pty"].append(snakebot_scan(device, [BAUD]))
            runs["pty1"].append(snakebot_scan(device, [BAUD], latency_ms=LOWERED_LATENCY_MS))
            runs["sdk"].append(sdk_scan(device))
            margin = equal_margin_ms(BAUD)
            runs["equal"].append(
                snakebot_scan(device, [BAUD], latency_ms=0, margin_ms=margin, echo="off")
            )
        rates = register_values.all_bauds()
        every_runs = [snakebot_scan(device, rates) for _ in range(ALL_RATES_ROUNDS)]
    against_limit("sim://, defaults:", runs["sim"], limit, SIM_GOAL_S)
    against_limit("paced pty, defaults:", runs["pty"], limit)
    against_limit(
        f"paced pty, {LOWERED_LATENCY_MS:g} ms latency timer:",
        runs["pty1"],
        physical_s(BAUD, LOWERED_LATENCY_MS),
    )
    sdk, _ = median(runs["sdk"])
    ours, _ = median(runs["equal"])
    print(
        f"   dynamixel-sdk ping loop:           {sdk:6.3f} s (reply timeout "
        f"{sdk_timeout_ms(BAUD):.2f} ms; {found_all(runs['sdk'])}: a reply the pty "
        "delivers later than its one wait is flushed before the next PING)"
    )
    print(
        f"   snakebot, same wait per ID:        {ours:6.3f} s ({ours / sdk:.3f}x the SDK's time, "
        f"the SDK PINGing a silent ID once, snakebot twice; goal {SDK_GOAL:g}x: "
        f"{verdict(ours <= SDK_GOAL * sdk, runs['equal'])})"
    )
    print(
        f"   per ID: SDK {per_id_ms(sdk):.3f} ms, snakebot {per_id_ms(ours):.3f} ms, of which "
        f"the wait {sdk_timeout_ms(BAUD):.3f} ms a PING"
    )
    every, fastest = median(every_runs)
    floor = scan_floor_s(rates)
    print(f"== {len(rates)} rates (--bauds all), defaults: {', '.join(map(str, rates))}")
    print(f"   physical limit:                    {floor:6.3f} s")
    print(
        f"   snakebot:                          {every:6.3f} s (best {fastest:.3f}; "
        f"{every / floor:.2f}x the limit; {verdict(True, every_runs)})"
    )
    pause = bus_scan.quiet_s()
    pauses = (len(rates) - 1) * pause
    probes = len(rates) * len(IDS)
    margins = 2 * probes * bus_scan.SCAN_MARGIN_S
    print(
        f"   above the limit: the second PING of every silent ID {floor:.3f} s; "
        f"{len(rates) - 1} pauses of {pause * 1e3:.1f} ms (servos drop a frame the last "
        f"rate's garbage began after {protocol.FRAME_RESET_S * 1e3:g} ms of quiet) "
        f"{pauses:.3f} s; the {bus_scan.SCAN_MARGIN_S * 1e3:g} ms host margin of "
        f"{2 * probes} silent PINGs {margins:.3f} s; the host's own time "
        f"{every - 2 * floor - pauses - margins:.3f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
