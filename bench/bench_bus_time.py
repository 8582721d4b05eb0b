"""Bus time per control tick for 5 and 18 servos against the 1 Mbps wire limit.

Each control tick the firmware's bus master sends one SYNC_WRITE of goal positions and
moving speeds to the whole roster, then one telemetry READ (Present Position through
Present Temperature) of the next servo, round robin, and waits for its status packet. Here the
firmware's own bus master (``firmware/core/bus_master.c`` through ``snakebot._core``)
produces the packets, and they go onto the emulated bus (``snakebot.sim.bus.bus``) with virtual
AX-12As on its virtual clock, which times every byte at 10 bits at the servos' baud rate
and honours their Return Delay Time. Measured: from the first byte of the tick's
SYNC_WRITE to the last byte of the status packet, averaged over the ticks of two rounds
of the roster.

Reference, computed in the same run: the wire limit, the tick's bytes (SYNC_WRITE +
READ + status packet, their sizes from the packets themselves) at 10 bits a byte at
1 Mbps, with no gaps. The ratio says what the bus adds to that: with Return Delay Time
0, nothing; with the AX-12's factory 500 us, the servo's wait before answering.
"""

from __future__ import annotations

import sys

from snakebot.core import ffi, lib
from snakebot.facts import devices
from snakebot.formats import protocol
from snakebot.sim.bus.bus import Bus
from snakebot.sim.servo.fast import VirtualServo

AX12 = devices.ax12()
BAUD = 1_000_000
BITS_PER_BYTE = 10
TICK_S = 0.010  # the firmware's control tick (BOARD_CONTROL_TICK_MS)
REPLY_DEADLINE_S = 0.005
ROSTERS = (5, 18)
RETURN_DELAYS_US = (0, 500)


class FirmwareBusMaster:
    """The firmware's bus master (C) with a roster of ``count`` servos, IDs 1..count."""

    def __init__(self, count: int) -> None:
        self._mem = ffi.new("uint8_t[]", lib.bus_master_size())
        self.b = ffi.cast("bus_master *", self._mem)
        lib.bus_init(self.b)
        self.ids = ffi.new("uint8_t[]", list(range(1, count + 1)))
        self.count = count
        lib.bus_set_roster(self.b, self.ids, count)
        self.goals = ffi.new("uint16_t[]", [512 + 3 * i for i in range(count)])
        self.speeds = ffi.new("uint16_t[]", [100] * count)
        self.out = ffi.new("uint8_t[]", 256)
        self.txn = ffi.new("bus_txn *")

    def tick(self, bus: Bus) -> tuple[float, int]:
        """One control tick on ``bus``: (bus seconds from first byte out to the end of the
        last reply, bytes on the wire)."""
        lib.bus_begin_tick(self.b)
        start = bus.now
        wire = 0
        while True:
            n = lib.bus_next(
                self.b, self.ids, self.goals, self.speeds, self.count, self.out, 256, self.txn
            )
            if n == 0:
                break
            packet = bytes(ffi.buffer(self.out, n))
            bus.master_write(packet)
            wire += n
            if self.txn.reply_len:
                deadline = bus.now + REPLY_DEADLINE_S
                got = b""
                while bus.run_until_master_data(deadline):
                    chunk = bus.master_read(256)
                    got += chunk
                    if lib.bus_rx(self.b, chunk, len(chunk)):
                        break
                lib.bus_rx_done(self.b)
                wire += len(got)
            else:  # a write: the master's UART is busy until its last byte is out
                bus.run_until(bus.now + n * BITS_PER_BYTE / BAUD)
        if lib.bus_timeouts(self.b):
            raise SystemExit("a telemetry READ went unanswered on the emulated bus")
        return bus.now - start, wire


def wire_limit_s(count: int) -> tuple[float, int]:
    """The tick's bytes at 1 Mbps, from the Protocol 1.0 packets built in Python."""
    goal, block = AX12.span("Goal Position", "Moving Speed")
    first, length = AX12.span("Present Position", "Present Temperature")
    sync = protocol.sync_write(goal, block, {i: bytes(block) for i in range(1, count + 1)})
    read = protocol.read(1, first, length)
    reply = protocol.status(1, 0, bytes(length))
    size = len(sync) + len(read) + len(reply)
    return size * BITS_PER_BYTE / BAUD, size


def measure(count: int, return_delay_us: int) -> tuple[float, int]:
    servos = [VirtualServo(i) for i in range(1, count + 1)]
    for s in servos:
        s.set_register("Return Delay Time", return_delay_us // 2)
    bus = Bus(servos, baudrate=BAUD)
    master = FirmwareBusMaster(count)
    times, sizes = [], []
    for _ in range(2 * count):
        t, size = master.tick(bus)
        times.append(t)
        sizes.append(size)
        bus.run_until(bus.now + TICK_S - t)  # the rest of the tick
    assert lib.bus_reads(master.b) == 2 * count
    return sum(times) / len(times), max(sizes)


def observed_in_qemu(seconds: float = 2.0) -> tuple[int, float, float] | None:
    """The real firmware under QEMU playing a table on the emulated snake5 (4 servos):
    (roster size, bytes on the bus per control tick, ticks per second), from the bus's
    byte counters and the controller's Bus Reads (one telemetry READ per tick). None if
    QEMU or the firmware image is not there."""
    import shutil
    import time

    from snakebot.link.controller.client import ControllerClient
    from snakebot.link.controller.playback import play, stop
    from snakebot.link.controller.upload import upload_gait
    from snakebot.model.gait import serpenoid
    from snakebot.model.robots import load_robot
    from snakebot.sim.serve import QEMU_FIRMWARE, EmulatedRobot

    if shutil.which("qemu-system-arm") is None or not QEMU_FIRMWARE.is_file():
        return None
    robot = load_robot("snake5")
    table = serpenoid(robot, 0.5, 3.14, 1.57, cycles=1, loop=True).gait_table()
    with (
        EmulatedRobot(robot, board="qemu") as emulated,
        ControllerClient.open(emulated.info.pc_link) as ctl,
    ):
        upload_gait(ctl, table, allow_new_servos=True)
        play(ctl, loop=True)
        time.sleep(0.3)

        def counters() -> tuple[int, int, float]:
            with emulated.lock:
                stats, now = emulated.bus.stats, emulated.bus.now
                out, back = stats.master_bytes_out, stats.master_bytes_in
            regs = ctl.read("Bus Reads", "Bus Timeouts")
            return out + back, regs["Bus Reads"] + regs["Bus Timeouts"], now

        b0, r0, t0 = counters()
        time.sleep(seconds)
        b1, r1, t1 = counters()
        stop(ctl)
    ticks = (r1 - r0) & 0xFFFF
    return robot.n_joints, (b1 - b0) / ticks, ticks / (t1 - t0)


def main() -> int:
    print(
        f"bus time per {1000 * TICK_S:.0f} ms control tick at {BAUD // 1000} kbps: firmware "
        "bus master (C) on the emulated bus, vs the wire limit"
    )
    print(
        f"{'servos':>6} {'RDT us':>6} {'bytes':>5} {'measured us':>11} {'wire limit us':>13} "
        f"{'ratio':>6} {'tick %':>6}"
    )
    ok = True
    for count in ROSTERS:
        limit, limit_bytes = wire_limit_s(count)
        for rdt in RETURN_DELAYS_US:
            t, size = measure(count, rdt)
            ratio = t / limit
            print(
                f"{count:>6} {rdt:>6} {size:>5} {1e6 * t:>11.1f} {1e6 * limit:>13.1f} "
                f"{ratio:>6.3f} {100 * t / TICK_S:>5.1f}%"
            )
            ok &= size == limit_bytes and t < TICK_S
    print(
        "ratio = measured / wire limit; with RDT 0 it is the bus's own overhead (none: the "
        "master sends back to back), with 500 us the servo's wait before it answers."
    )
    seen = observed_in_qemu()
    if seen is None:
        print("(QEMU cross-check skipped: no qemu-system-arm or no build/qemu/firmware.elf)")
    else:
        count, per_tick, rate = seen
        _, expected = wire_limit_s(count)
        print(
            f"cross-check, the firmware in QEMU playing on {count} emulated servos: "
            f"{per_tick:.1f} bytes on the bus per control tick (the C bus master above "
            f"gives {expected} for {count}; ratio {per_tick / expected:.3f}), "
            f"{rate:.0f} ticks per second of bus time"
        )
        ok &= abs(per_tick - expected) <= 0.05 * expected
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
