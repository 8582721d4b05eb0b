"""Upload throughput as a fraction of the PC link's wire capacity at 57600 baud.

The controller's real C device logic runs behind a pseudo-terminal whose relay paces
every byte at 57600 baud wire time (10 bits a byte, each direction on its own wire,
like the CM-530's full-duplex UART), so the figures mean what they would on hardware
with a zero-latency adapter. Measured in the same run, on the same line:

* the line itself: a stream of PINGs, several in flight, timed from the first byte out
  to the last reply in (what the relay really delivers);
* `snakebot upload` as shipped, the whole command (identify, the checks, every chunk,
  the commit, the verification READ) for the largest table and for small ones;
* the chunk stream alone (the WRITEs and the commit, no checks): the ceiling of the
  command;
* the same upload stop-and-wait (one WRITE at a time), the naive reference.

Goal: the whole upload of the largest table carries table bytes at >= 85 % of the
wire's 5760 bytes/s. A chunk WRITE is 73 bytes for 64 table bytes, so 87.7 % is the
ceiling for any upload through the 64-byte window.
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np

from snakebot import protocol
from snakebot.controller.client import ControllerClient
from snakebot.controller.transfer import stream_writes
from snakebot.controller.upload import chunk_writes, commit_write
from snakebot.controller.uploader import upload_gait
from snakebot.errors import SnakebotError
from snakebot.gaittable import GaitTable, max_frames
from snakebot.protocol import Instruction
from snakebot.sim.controller_pty import ControllerPty, is_commit, is_upload_chunk
from snakebot.transport.timing import STATUS_OVERHEAD

BAUD = 57600
WIRE_BYTES_PER_S = BAUD / 10
GOAL = 0.85
CEILING = 64 / 73
RUNS = 5
PINGS = 200
SETTLE_S = 0.5
SMALL_FRAMES = (10, 60)


def sine_table(frames: int) -> GaitTable:
    """4 joints, ``frames`` frames of a sine wave; max_frames(4) makes exactly 2048 bytes."""
    k = np.arange(frames)[:, None]
    ticks = 512 + np.round(200 * np.sin(2 * np.pi * k / frames + np.arange(4))).astype(int)
    return GaitTable((10, 11, 15, 16), 20, True, ((200, 824),) * 4, ticks, {})


def biggest_table() -> GaitTable:
    return sine_table(max_frames(4))


def line_capacity(ctl: ControllerClient) -> float:
    """Bytes per second the paced line carries one way (PING out, status back)."""
    ping = protocol.ping(ctl.id)
    best = 0.0
    for _ in range(3):
        result = stream_writes(ctl.link, ctl.id, [ping] * PINGS, window=16)
        if result.complete:  # a round that lost replies (a starved relay) does not count
            best = max(best, PINGS * len(ping) / result.seconds)
        else:
            settle(ctl)
    return best


def settle(ctl: ControllerClient) -> None:
    """After a stream that gave up, let what is still in flight arrive and drop it, so
    that the next exchange does not hear it."""
    time.sleep(SETTLE_S)
    ctl.link.port.reset_input_buffer()


def upload_rate(ctl: ControllerClient, table: GaitTable, window: int) -> float:
    """Median table bytes per second of the whole upload command (an upload that needed
    a second attempt, as on a loaded machine, counts with its full time)."""
    rates = []
    for _ in range(RUNS):
        try:
            report = upload_gait(ctl, table, window=window)
        except SnakebotError as exc:  # e.g. a relay starved on a loaded machine
            print(f"   (an upload of {table.size} bytes failed: {exc})")
            settle(ctl)
            continue
        if not report.paced:
            raise SystemExit("the relay did not pace the line: no share of the wire to give")
        if report.attempts > 1:
            print(f"   (an upload of {table.size} bytes took {report.attempts} attempts)")
        rates.append(report.bytes_per_s)
    if not rates:
        raise SystemExit(f"no upload of {table.size} bytes got through")
    return statistics.median(rates)


def stream_rate(ctl: ControllerClient, table: GaitTable, window: int) -> float:
    """Median table bytes per second of the chunk WRITEs and the commit alone."""
    data = table.encode()
    packets = [protocol.write(ctl.id, a, p) for a, p in chunk_writes(data, controller=ctl.table)]
    packets.append(protocol.write(ctl.id, *commit_write(data, ctl.table)))
    rates = []
    for _ in range(RUNS):
        result = stream_writes(ctl.link, ctl.id, packets, window)
        if result.complete:
            rates.append(len(data) / result.seconds)
        else:
            print(f"   (a chunk stream was not completely acknowledged: {result})")
            settle(ctl)
    if not rates:
        raise SystemExit("no chunk stream got through")
    return statistics.median(rates)


def exchange_floor(packets: list[bytes]) -> int:
    """Byte times one upload needs on the wire at best (no latency, the controller
    answering at once), from the packets the host sent: each READ or WRITE before the
    first chunk and after the commit waits for its status packet (READ's carries the
    bytes asked for), while the chunks and the commit stream back to back and only the
    last acknowledgement adds its own time."""
    total = 0
    streaming = False
    for packet in packets:
        if is_upload_chunk(packet) or is_commit(packet):
            total += len(packet)
            streaming = True
            continue
        if streaming:  # the stream ends with the last acknowledgement coming back
            total += STATUS_OVERHEAD
            streaming = False
        reply = STATUS_OVERHEAD + (packet[6] if packet[4] == Instruction.READ else 0)
        total += len(packet) + reply
    return total + (STATUS_OVERHEAD if streaming else 0)


def overlap_floor(packets: list[bytes]) -> int:
    """Byte times one upload would need if every exchange overlapped the chunk stream
    (the link is full duplex, so replies could come back while chunks go out): every
    byte the host sends, one after another, then the last exchange's reply (the
    verification READ's), which cannot start before its instruction has arrived. No
    ordering of these packets does better, whatever the latency."""
    last = packets[-1]
    tail = STATUS_OVERHEAD + (last[6] if last[4] == Instruction.READ else 0)
    return sum(len(p) for p in packets) + tail


def upload_exchanges(
    server: ControllerPty, ctl: ControllerClient, table: GaitTable
) -> tuple[int, int]:
    """(:func:`exchange_floor`, :func:`overlap_floor`) of one more upload like the
    others (a roster to check), from the packets the controller received."""
    for _ in range(3):
        first = len(server.host_packets)
        try:
            if upload_gait(ctl, table, window=8).attempts == 1:
                packets = server.host_packets[first:]
                return exchange_floor(packets), overlap_floor(packets)
        except SnakebotError:
            settle(ctl)
    raise SystemExit("no clean upload to count the exchanges of")


def percent(rate: float) -> str:
    return f"{rate:7.0f} bytes/s = {100 * rate / WIRE_BYTES_PER_S:5.1f} % of the wire"


def main() -> int:
    table = biggest_table()
    small = [sine_table(frames) for frames in SMALL_FRAMES]
    with ControllerPty(robot="snake5", baudrate=BAUD) as server:
        with ControllerClient.open(server.device, BAUD) as ctl:
            line = line_capacity(ctl)
            pipelined = upload_rate(ctl, table, window=8)
            floor, overlapped = (table.size / n for n in upload_exchanges(server, ctl, table))
            stream = stream_rate(ctl, table, window=8)
            stop_and_wait = upload_rate(ctl, table, window=1)
            smalls = [(t.size, upload_rate(ctl, t, window=8)) for t in small]
    frac = pipelined / WIRE_BYTES_PER_S
    print(
        f"PC link {BAUD} baud = {WIRE_BYTES_PER_S:.0f} bytes/s of wire; ceiling through the "
        f"64-byte window {100 * CEILING:.1f} %; median of {RUNS} uploads each"
    )
    print(f"line (PING stream, same relay):            {percent(line)}")
    print(f"largest table ({table.size} bytes):")
    print(f"  chunk stream alone (no checks):          {percent(stream)}")
    print(f"  whole upload, stop-and-wait:             {percent(stop_and_wait)}")
    print(f"  whole upload, as shipped (window 8):     {percent(pipelined)}")
    print(
        f"  the best its exchanges allow (READs and WRITEs before and after the stream "
        f"waiting for their answers, no latency): {100 * floor:.1f} % of the wire"
    )
    print(
        f"  the best any order of the same packets allows (every exchange overlapping the "
        f"stream, full duplex, no latency): {100 * overlapped:.1f} % of the wire"
        + (
            f": below the goal of {100 * GOAL:.0f} %, which the 64-byte upload window and "
            "the checks' READs put out of reach"
            if overlapped < GOAL
            else ""
        )
    )
    for size, rate in smalls:
        print(f"small table ({size:4d} bytes), whole upload:  {percent(rate)}")
    print(
        f"ratio whole upload / wire capacity: {frac:.3f} (goal >= {GOAL}: "
        f"{'met' if frac >= GOAL else 'MISS'}); whole upload / chunk stream: "
        f"{pipelined / stream:.3f}; of its exchanges' best: "
        f"{frac / floor:.3f}; vs stop-and-wait: {pipelined / stop_and_wait:.2f}x"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
