"""Benchmark: `snakebot bus scan` of all 254 IDs against the physical limit, against
dynamixel-sdk's ping loop at equal settings, and over every tabulated rate.

The bus is the emulator's paced pseudo-terminal (`snakebot sim bus --pty`, in its own
process, as a real bus is outside the host's): virtual AX-12As that answer in real
time with the longest Return Delay Time (508 us), so the timing of a silent ID is what a
real bus gives. Measured in the same run:

* at 1 Mbps, the physical limit: per ID, a PING and a status packet on the wire (10 bits
  a byte) plus the return delay (about 0.16 s); snakebot's scan with a tight margin (no
  USB latency, ``TIGHT_MARGIN_MS``), goal within 3x that limit;
* dynamixel-sdk's ``ping`` over every ID, and snakebot's scan waiting for a silent ID
  exactly as long as the SDK's formula waits for a reply (its latency timer set to 0 for
  both), and told, as the SDK assumes, that the line has no echo (otherwise snakebot
  spends one reply timeout asking the line first): snakebot should take no longer;
* a scan of every tabulated rate (``--bauds all``) with the tight margin, goal under 5 s,
  beside that list's physical limit: per ID the least a scan must wait, a PING, the
  return delay and the first byte of a reply (the rest of the status only where a servo
  answers). If that limit is over 5 s already, the goal cannot be met and the line says so.
  The time above the limit is split into the margins a reliable scan keeps (the quiet
  pause before each further rate, which lets servos drop a frame begun by the last
  rate's garbage, and the host margin of every silent ID) and the rest, the host's own.

At equal settings both sides wait the same for a silent ID, so that wait alone bounds
how much faster than the SDK snakebot can be: the lines give the time per ID beside it.

A scan that misses a servo is marked MISS whatever its time.

    .venv/bin/python bench/bench_scan.py
"""

from __future__ import annotations

import os
import signal
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
from snakebot.link.transport import BusTiming, open_port, settings
from snakebot.link.transport.timing import wire_time_s

BAUD = 1_000_000
IDS = range(0, protocol.MAX_ID + 1)
SERVOS = (1, 2, 3)
RETURN_DELAY_US = bus_scan.longest_return_delay_us()  # the servos are set to it
PHYSICAL_GOAL = 3.0
ALL_RATES_GOAL_S = 5.0
TIGHT_MARGIN_MS = 0.5
ROUNDS = 5
ALL_RATES_ROUNDS = 2
SERVER_START_S = 30.0
PING = protocol.ping(1)
STATUS_LEN = len(protocol.status(1, 0, b""))


def physical_s(baud: int) -> float:
    """The issue's limit at one rate: every ID's PING, status packet and return delay."""
    per_id = wire_time_s(len(PING) + STATUS_LEN, baud) + RETURN_DELAY_US * 1e-6
    return len(IDS) * per_id


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
    device: str, bauds: list[int], margin_ms: float, echo: str = "auto"
) -> tuple[float, list[int]]:
    os.environ[settings.ENV_LATENCY_MS] = "0"
    os.environ[settings.ENV_MARGIN_MS] = f"{margin_ms}"
    os.environ[settings.ENV_ECHO] = echo
    with open_port(device, bauds[0], timeout=0) as link:
        start = time.perf_counter()
        found = bus_scan.scan(link, IDS, bauds)
        return time.perf_counter() - start, [s.id for s in found]


def sdk_scan(device: str) -> tuple[float, list[int]]:
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


def best(runs: list[tuple[float, list[int]]]) -> tuple[float, list[int]]:
    """The fastest run that found every servo, else the fastest run."""
    complete = [r for r in runs if r[1] == list(SERVOS)]
    return min(complete or runs)


def verdict(ok: bool, found: list[int]) -> str:
    if found != list(SERVOS):
        return f"MISS (found {found})"
    return "met" if ok else "MISS"


def main() -> int:
    sdk_port.LATENCY_TIMER = 0  # no USB adapter here: both sides wait without it
    limit = physical_s(BAUD)
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(f"== 254 IDs at {BAUD} bps, servos {SERVOS}, Return Delay {RETURN_DELAY_US:g} us")
    print(f"   physical limit:                 {limit:6.3f} s")
    with served_bus() as device:
        runs: dict[str, list[tuple[float, list[int]]]] = {"tight": [], "sdk": [], "equal": []}
        for _ in range(ROUNDS):  # alternate, so load from other processes hits each alike
            runs["sdk"].append(sdk_scan(device))
            runs["equal"].append(snakebot_scan(device, [BAUD], equal_margin_ms(BAUD), echo="off"))
            runs["tight"].append(snakebot_scan(device, [BAUD], TIGHT_MARGIN_MS))
        rates = register_values.all_bauds()
        every_runs = [
            snakebot_scan(device, rates, TIGHT_MARGIN_MS) for _ in range(ALL_RATES_ROUNDS)
        ]
    tight, found = best(runs["tight"])
    print(
        f"   snakebot, margin {TIGHT_MARGIN_MS} ms:         {tight:6.3f} s "
        f"({tight / limit:.2f}x the limit; goal {PHYSICAL_GOAL}x: "
        f"{verdict(tight / limit <= PHYSICAL_GOAL, found)})"
    )
    sdk, sdk_found = best(runs["sdk"])
    ours, found = best(runs["equal"])
    print(
        f"   dynamixel-sdk ping loop:        {sdk:6.3f} s (reply timeout "
        f"{sdk_timeout_ms(BAUD):.2f} ms; {verdict(True, sdk_found)})"
    )
    print(
        f"   snakebot, same wait per ID:     {ours:6.3f} s ({ours / sdk:.3f}x the SDK; "
        f"goal 1.0x: {verdict(ours <= sdk, found)})"
    )
    print(
        f"   per ID: SDK {per_id_ms(sdk):.3f} ms, snakebot {per_id_ms(ours):.3f} ms, of which "
        f"the wait {sdk_timeout_ms(BAUD):.3f} ms (so at best "
        f"{sdk_timeout_ms(BAUD) / per_id_ms(sdk):.2f}x the SDK)"
    )
    every, found = best(every_runs)
    floor = scan_floor_s(rates)
    print(f"== {len(rates)} rates (--bauds all): {', '.join(map(str, rates))}")
    print(
        f"   physical limit:                 {floor:6.3f} s"
        + (
            f" (over the {ALL_RATES_GOAL_S:g} s goal: the goal cannot be met)"
            if floor >= ALL_RATES_GOAL_S
            else ""
        )
    )
    print(
        f"   snakebot, margin {TIGHT_MARGIN_MS} ms:         {every:6.3f} s "
        f"({every / floor:.2f}x the limit; goal {ALL_RATES_GOAL_S:g} s: "
        f"{verdict(every < ALL_RATES_GOAL_S, found)})"
    )
    pause = bus_scan.quiet_s(BusTiming(margin_s=TIGHT_MARGIN_MS * 1e-3))
    pauses = (len(rates) - 1) * pause
    probes = len(rates) * len(IDS)
    margins = probes * TIGHT_MARGIN_MS * 1e-3
    rest = every - floor - pauses - margins
    print(
        f"   above the limit: {len(rates) - 1} pauses of {pause * 1e3:.1f} ms (servos drop "
        f"a frame the last rate's garbage began after {protocol.FRAME_RESET_S * 1e3:g} ms "
        f"of quiet) {pauses:.3f} s; the {TIGHT_MARGIN_MS} ms host margin of {probes} "
        f"silent IDs (a reply's first byte reaches the host late) {margins:.3f} s; the "
        f"host's own time {rest:.3f} s ({rest / probes * 1e6:.0f} us an ID)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
