"""Benchmark: `snakebot bus scan` of all 254 IDs against the physical limit and against
dynamixel-sdk's ping loop at equal settings.

The bus is the emulator's paced pseudo-terminal (``snakebot.sim.transports.PtyServer``):
virtual AX-12As that answer in real time, with the largest Return Delay Time (508 us),
so the timing of a silent ID is what a real bus gives. Measured in the same run:

* the physical limit: per ID, a PING and a status packet on the wire (10 bits a byte)
  plus the return delay; 254 of them (about 0.16 s at 1 Mbps);
* snakebot's scan with a tight reply timeout (no USB latency, ``TIGHT_MARGIN_MS``), goal
  within 3x the physical limit;
* dynamixel-sdk's ``ping`` over every ID, and snakebot's scan with the same reply timeout
  the SDK's formula gives (its latency timer set to 0 for both): snakebot should take no
  longer;
* a scan of every tabulated rate (``--bauds all``), goal under 5 s.

A scan that misses a servo is marked MISS whatever its time.

    .venv/bin/python bench/bench_scan.py
"""

from __future__ import annotations

import os
import sys
import time

import dynamixel_sdk
import dynamixel_sdk.port_handler as sdk_port

from snakebot import protocol, servo_ops
from snakebot.sim.options import SimOptions
from snakebot.sim.transports import PtyServer
from snakebot.transport import open_port, settings
from snakebot.transport.timing import wire_time_s

BAUD = 1_000_000
IDS = range(0, protocol.MAX_ID + 1)
SERVOS = (1, 2, 3)
RETURN_DELAY_US = 508.0  # the AX-12's largest (Return Delay Time 254)
PHYSICAL_GOAL = 3.0
ALL_RATES_GOAL_S = 5.0
TIGHT_MARGIN_MS = 0.5
ROUNDS = 3
PING = protocol.ping(1)
STATUS_LEN = len(protocol.status(1, 0, b""))


def physical_s(baud: int) -> float:
    per_id = wire_time_s(len(PING) + STATUS_LEN, baud) + RETURN_DELAY_US * 1e-6
    return len(IDS) * per_id


def sdk_timeout_ms(baud: int) -> float:
    """dynamixel-sdk's wait for a PING's status packet (PortHandler.setPacketTimeout)."""
    return wire_time_s(STATUS_LEN, baud) * 1e3 + sdk_port.LATENCY_TIMER * 2.0 + 2.0


def snakebot_scan(device: str, bauds: list[int], margin_ms: float) -> tuple[float, list[int]]:
    os.environ[settings.ENV_LATENCY_MS] = "0"
    os.environ[settings.ENV_MARGIN_MS] = f"{margin_ms}"
    os.environ[settings.ENV_RETURN_DELAY_US] = f"{RETURN_DELAY_US}"
    with open_port(device, bauds[0], timeout=0) as link:
        start = time.perf_counter()
        found = servo_ops.scan(link, IDS, bauds)
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
    equal_margin_ms = sdk_timeout_ms(BAUD) - (physical_s(BAUD) / len(IDS)) * 1e3
    query = f"ids={','.join(map(str, SERVOS))}&return_delay={RETURN_DELAY_US:g}"
    limit = physical_s(BAUD)
    print(f"== machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    print(f"== 254 IDs at {BAUD} bps, servos {SERVOS}, Return Delay {RETURN_DELAY_US:g} us")
    print(f"   physical limit:                 {limit:6.3f} s")
    with PtyServer(SimOptions.from_query(query).build_bus()) as server:
        device = server.device
        runs: dict[str, list[tuple[float, list[int]]]] = {"tight": [], "sdk": [], "equal": []}
        for _ in range(ROUNDS):  # alternate, so load from other processes hits each alike
            runs["sdk"].append(sdk_scan(device))
            runs["equal"].append(snakebot_scan(device, [BAUD], equal_margin_ms))
            runs["tight"].append(snakebot_scan(device, [BAUD], TIGHT_MARGIN_MS))
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
            f"   snakebot, same reply timeout:   {ours:6.3f} s ({ours / sdk:.2f}x the SDK; "
            f"goal 1.0x: {verdict(ours <= sdk, found)})"
        )
        rates = servo_ops.all_bauds()
        every, found = snakebot_scan(device, rates, TIGHT_MARGIN_MS)
        print(
            f"   snakebot, {len(rates)} rates (--bauds all): {every:6.3f} s "
            f"(goal {ALL_RATES_GOAL_S:g} s: {verdict(every < ALL_RATES_GOAL_S, found)})"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
