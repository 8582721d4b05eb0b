"""Upload throughput as a fraction of the PC link's wire capacity at 57600 baud.

The controller's real C device logic runs behind a pseudo-terminal whose relay paces
every byte at 57600 baud wire time (10 bits a byte, each direction on its own wire,
like the CM-530's full-duplex UART), so the figures mean what they would on hardware
with a zero-latency adapter. Measured in the same run, on the same line:

* the line itself: a stream of PINGs, several in flight, timed from the first byte out
  to the last reply in (what the relay really delivers);
* `snakebot upload` as shipped (several WRITEs in flight);
* the same upload stop-and-wait (one WRITE at a time), the naive reference.

Goal: the upload carries table bytes at >= 85 % of the wire's 5760 bytes/s. A chunk
WRITE is 73 bytes for 64 table bytes, so 87.7 % is the ceiling for any upload through
the 64-byte window.
"""

from __future__ import annotations

import statistics
import sys

import numpy as np

from snakebot import protocol
from snakebot.controller.client import ControllerClient
from snakebot.controller.transfer import stream_writes
from snakebot.controller.uploader import upload_gait
from snakebot.gaittable import GaitTable, max_frames
from snakebot.sim.controller_pty import ControllerPty

BAUD = 57600
WIRE_BYTES_PER_S = BAUD / 10
GOAL = 0.85
CEILING = 64 / 73
RUNS = 5
PINGS = 200


def biggest_table() -> GaitTable:
    """4 joints, as many frames as fit: exactly 2048 bytes."""
    frames = max_frames(4)
    k = np.arange(frames)[:, None]
    ticks = 512 + np.round(200 * np.sin(2 * np.pi * k / frames + np.arange(4))).astype(int)
    return GaitTable((10, 11, 15, 16), 20, True, ((200, 824),) * 4, ticks, {})


def line_capacity(ctl: ControllerClient) -> float:
    """Bytes per second the paced line carries one way (PING out, status back)."""
    ping = protocol.ping(ctl.id)
    best = 0.0
    for _ in range(3):
        result = stream_writes(ctl.link, ctl.id, [ping] * PINGS, window=16)
        assert result.complete, result
        best = max(best, PINGS * len(ping) / result.seconds)
    return best


def upload_rate(ctl: ControllerClient, table: GaitTable, window: int) -> float:
    rates = []
    for _ in range(RUNS):
        report = upload_gait(ctl, table, window=window)
        assert report.attempts == 1
        rates.append(report.bytes_per_s)
    return statistics.median(rates)


def main() -> int:
    table = biggest_table()
    with ControllerPty(robot="snake5", baudrate=BAUD) as server:
        with ControllerClient.open(server.device, BAUD) as ctl:
            line = line_capacity(ctl)
            pipelined = upload_rate(ctl, table, window=8)
            stop_and_wait = upload_rate(ctl, table, window=1)
    frac = pipelined / WIRE_BYTES_PER_S
    print(
        f"table: {table.size} bytes, PC link {BAUD} baud = {WIRE_BYTES_PER_S:.0f} bytes/s "
        f"of wire; ceiling through the 64-byte window {100 * CEILING:.1f} %"
    )
    print(
        f"line (PING stream, same relay):  {line:7.0f} bytes/s = "
        f"{100 * line / WIRE_BYTES_PER_S:5.1f} % of the wire"
    )
    print(
        f"upload, stop-and-wait:           {stop_and_wait:7.0f} bytes/s = "
        f"{100 * stop_and_wait / WIRE_BYTES_PER_S:5.1f} % of the wire"
    )
    print(
        f"upload, as shipped (window 8):   {pipelined:7.0f} bytes/s = "
        f"{100 * frac:5.1f} % of the wire"
    )
    print(
        f"ratio upload / wire capacity: {frac:.3f} (goal >= {GOAL}); "
        f"upload / measured line: {pipelined / line:.3f}; "
        f"vs stop-and-wait: {pipelined / stop_and_wait:.2f}x"
    )
    print("GOAL MET" if frac >= GOAL else "BELOW GOAL")
    return 0


if __name__ == "__main__":
    sys.exit(main())
