"""Upload throughput as a fraction of the PC link's wire capacity at 57600 baud.

The controller's real C device logic runs behind a pseudo-terminal whose relay paces
every byte at 57600 baud wire time (10 bits a byte, each direction on its own wire,
like the CM-530's full-duplex UART), so the figures mean what they would on hardware
with a zero-latency adapter. Measured in the same run, on the same line:

* the line itself: a stream of PINGs, several in flight, timed from the first byte out
  to the last reply in (what the relay really delivers);
* `snakebot upload` as shipped, the whole command for the largest table the controller
  takes (its Table Capacity, read from it) and for small ones. The command is one stream
  with several packets in flight: the checks' READs (identify, what it holds, Table
  Capacity, the roster) first, their answers checked while the first chunks go out; the
  chunks (Upload Data, Window Page and window page Upload Data 2 in one WRITE: 190 table
  bytes for 200 sent, as the controller has that page); the commit, held until the
  checks have passed; and the verification READ right behind it;
* the same command with chunks of Upload Data's size, as a controller without the page
  gets them (64-byte chunks, 73 bytes sent each: the reference the long chunks are
  measured against);
* the chunk stream alone (the WRITEs and the commit, no checks): the ceiling of the
  command;
* the same upload stop-and-wait (one packet at a time), the naive reference.

Goal: the whole upload of the largest table carries table bytes at >= 85 % of the
wire's 5760 bytes/s. The bounds printed come from the packets themselves: the chunk
stream's table bytes over the bytes it sends, and the whole command's packets on two
wires (each instruction after the one before it on the host's wire, each answer after
its instruction and the answer before it on the controller's, the commit after the
checks' answers, no latency).
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np

from snakebot.errors import SnakebotError
from snakebot.formats import protocol
from snakebot.formats.gaittable import GaitTable, max_frames, table_size
from snakebot.formats.protocol import Instruction
from snakebot.formats.upload_writes import chunk_writes, commit_write
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.upload import CAPACITY, upload_gait
from snakebot.link.controller.upload_stream import stream_writes
from snakebot.link.transport.timing import STATUS_OVERHEAD
from snakebot.sim.controller_pty import ControllerPty, is_commit, is_upload_chunk

BAUD = 57600
WIRE_BYTES_PER_S = BAUD / 10
GOAL = 0.85
RUNS = 3
PINGS = 200
SETTLE_S = 0.5
SMALL_FRAMES = (10, 60)


def sine_table(frames: int) -> GaitTable:
    """4 joints, ``frames`` frames of a sine wave."""
    k = np.arange(frames)[:, None]
    ticks = 512 + np.round(200 * np.sin(2 * np.pi * k / frames + np.arange(4))).astype(int)
    return GaitTable((10, 11, 15, 16), 20, True, ((200, 824),) * 4, ticks, {})


def biggest_table(capacity: int) -> GaitTable:
    """The largest 4-joint table within ``capacity`` bytes (and the gait format's limit)."""
    per_frame = table_size(4, 1) - table_size(4, 0)
    return sine_table(min(max_frames(4), (capacity - table_size(4, 0)) // per_frame))


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


def stream_packets(ctl: ControllerClient, table: GaitTable) -> list[bytes]:
    """The chunk WRITEs (long chunks) and the commit of ``table``."""
    data = table.encode()
    chunks = chunk_writes(data, controller=ctl.table, long_chunks=True)
    packets = [protocol.write(ctl.id, a, p) for a, p in chunks]
    return [*packets, protocol.write(ctl.id, *commit_write(data, ctl.table))]


def upload_rate(
    ctl: ControllerClient, table: GaitTable, window: int, long_chunks: bool = True
) -> float:
    """Median table bytes per second of the whole upload command (an upload that needed
    a second attempt, as on a loaded machine, counts with its full time)."""
    rates = []
    for _ in range(RUNS):
        try:
            report = upload_gait(ctl, table, window=window, long_chunks=long_chunks)
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
    packets = stream_packets(ctl, table)
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
    """Byte times one upload needs on the wire at best, from the packets the host sent:
    on the host's wire each packet follows the one before it (the commit also waits
    until the answers to every packet but the chunks before it are in: the checks); on
    the controller's wire each answer follows its packet and the answer before it (a
    READ's carries the bytes asked for). No latency, the controller answering at once,
    a window never full: the command ends with the last answer."""
    out = back = checked = 0
    for packet in packets:
        if is_commit(packet):
            out = max(out, checked)
        out += len(packet)
        back = max(back, out) + STATUS_OVERHEAD
        if packet[4] == Instruction.READ:
            back += packet[6]
        if not (is_upload_chunk(packet) or is_commit(packet)):
            checked = back
    return back


def upload_exchanges(
    server: ControllerPty, ctl: ControllerClient, table: GaitTable, long_chunks: bool = True
) -> int:
    """:func:`exchange_floor` of one more upload like the others (a roster to check),
    from the packets the controller received."""
    for _ in range(3):
        first = len(server.host_packets)
        try:
            report = upload_gait(ctl, table, window=8, long_chunks=long_chunks)
            if report.attempts == 1:
                return exchange_floor(server.host_packets[first:])
        except SnakebotError:
            settle(ctl)
    raise SystemExit("no clean upload to count the exchanges of")


def percent(rate: float) -> str:
    return f"{rate:7.0f} bytes/s = {100 * rate / WIRE_BYTES_PER_S:5.1f} % of the wire"


def miss_reason(frac: float, floor: float, stream: float) -> str:
    """Why the goal was missed, from the figures of the same run."""
    if floor < GOAL:
        return (
            f"the command's own packets allow at most {100 * floor:.1f} % of the wire: "
            "fewer bytes outside the chunk stream are needed"
        )
    if stream / WIRE_BYTES_PER_S < GOAL:
        return (
            f"even the chunk stream alone reached only {100 * stream / WIRE_BYTES_PER_S:.1f} "
            "%: the relay or the machine did not keep the line busy (a loaded machine?)"
        )
    return (
        f"the command reached {frac / floor:.3f} of what its packets allow: the time lost "
        "is the host's and the relay's turnaround between the packets (latency), not the "
        "packets themselves"
    )


def main() -> int:
    small = [sine_table(frames) for frames in SMALL_FRAMES]
    with ControllerPty(robot="snake5", baudrate=BAUD) as server:
        with ControllerClient.open(server.device, BAUD) as ctl:
            capacity = ctl.read(CAPACITY)[CAPACITY]
            table = biggest_table(capacity)
            line = line_capacity(ctl)
            pipelined = upload_rate(ctl, table, window=8)
            exchanges = upload_exchanges(server, ctl, table)
            floor = table.size / exchanges
            stream = stream_rate(ctl, table, window=8)
            stop_and_wait = upload_rate(ctl, table, window=1)
            smalls = [(t.size, upload_rate(ctl, t, window=8)) for t in small]
            packets = stream_packets(ctl, table)
            outside = exchanges - sum(len(p) for p in packets)
            short_chunks = upload_rate(ctl, table, window=8, long_chunks=False)
            short_floor = table.size / upload_exchanges(server, ctl, table, long_chunks=False)
    frac = pipelined / WIRE_BYTES_PER_S
    ceiling = table.size / sum(len(p) for p in packets)
    print(
        f"PC link {BAUD} baud = {WIRE_BYTES_PER_S:.0f} bytes/s of wire; the largest table's "
        f"chunk stream ({len(packets) - 1} long chunks and the commit) carries table bytes "
        f"at {100 * ceiling:.1f} % of what it sends; median of {RUNS} uploads each"
    )
    print(f"line (PING stream, same relay):            {percent(line)}")
    print(f"largest table ({table.size} bytes; the controller's Table Capacity: {capacity}):")
    print(f"  chunk stream alone (no checks):          {percent(stream)}")
    print(f"  whole upload, stop-and-wait:             {percent(stop_and_wait)}")
    print(f"  whole upload, 64-byte chunks (window 8): {percent(short_chunks)}")
    print(f"    the best its packets allow:            {100 * short_floor:.1f} % of the wire")
    print(f"  whole upload, as shipped (window 8):     {percent(pipelined)}")
    print(
        f"  the best its packets allow (the checks, chunks, commit and verification in "
        f"one stream, no latency): {100 * floor:.1f} % of the wire"
    )
    print(
        f"    of its {exchanges} byte times at best, {outside} ({100 * outside / exchanges:.1f} %) "
        "are the checks' packets (identify and what it holds, Table Capacity, the roster), "
        "the verification READ and the answer it waits for"
    )
    for size, rate in smalls:
        print(f"small table ({size:4d} bytes), whole upload:  {percent(rate)}")
    print(
        f"ratio whole upload / wire capacity: {frac:.3f} (goal >= {GOAL}: "
        f"{'met' if frac >= GOAL else 'MISS'}); whole upload / chunk stream: "
        f"{pipelined / stream:.3f}; of its packets' best: "
        f"{frac / floor:.3f}; vs stop-and-wait: {pipelined / stop_and_wait:.2f}x; vs 64-byte "
        f"chunks: {pipelined / short_chunks:.3f}x"
    )
    if frac < GOAL:
        print(f"missed: {miss_reason(frac, floor, stream)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
