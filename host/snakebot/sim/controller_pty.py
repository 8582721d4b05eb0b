"""The controller's real C device logic behind a pseudo-terminal, in process.

``firmware/core/ctl_device.c`` is what the CM-530 firmware runs on its PC link (the
control table, upload and commit, commands, player, safety, bus master). Here it runs
through the host's cffi build of the same C (``snakebot._core``), minus the HAL:

* the PC link is a pseudo-terminal that host tools open like the CM-530's USB port;
* the bus side drives an emulated servo bus (:class:`snakebot.sim.bus.bus.Bus`, virtual AX-12s)
  in virtual time, one control tick every ``tick_ms`` of wall time, as the firmware's
  main loop does; or, with no bus, every telemetry READ times out;
* optionally the line is paced at a baud rate (10 bits a byte, each direction on its own
  wire, as a full-duplex UART), so throughput figures mean what they would on hardware;
* optionally a line filter sees every packet the host sends, by index, and may damage or
  drop it (:class:`CorruptOnce`, :class:`CutAfter`), to test recovery.

::

    from snakebot.sim.controller_pty import ControllerPty

    with ControllerPty(robot="snake5") as server:
        print(server.device)        # /dev/pts/N: `snakebot upload walk.gait --port ...`

``python -m snakebot.sim.controller_pty --robot snake5`` runs one until Ctrl-C.
"""

from __future__ import annotations

import collections
import os
import select
import sys
import time
from collections.abc import Callable

from snakebot.core import ffi, lib
from snakebot.model.player import TICK_MS
from snakebot.sim.bus.bus import Bus
from snakebot.sim.bus.clock import byte_time
from snakebot.sim.errors import SimInputError
from snakebot.sim.options import SimOptions
from snakebot.sim.transports.base import RawPty, ThreadedServer
from snakebot.sim.transports.pump import ServerThread

BUS_BAUD = 1_000_000
"""The Dynamixel bus rate (BOARD_BUS_BAUD)."""

BUS_REPLY_TIMEOUT_S = 0.005
"""How long, in bus time, the bus master waits for a servo's status packet."""

PARTIAL_PACKET_S = 0.1
"""A packet still incomplete after this long is passed on as it is (the device's parser
deals with it), so a truncated packet cannot stall the line."""

MIN_WAKE_S = 0.0005
"""Shortest sleep of the server loop: paced bytes are handed over in small batches at
their scheduled times (the schedule itself is exact, so the rate is)."""

LineFilter = Callable[[int, bytes], "bytes | None"]
"""``filter(index, packet)`` for every packet the host sends (index from 0): the bytes
to put on the wire instead (``packet`` unchanged, damaged, ...) or None to lose it."""


# -- line faults -------------------------------------------------------------------------


def is_upload_chunk(packet: bytes, offset: int | None = None) -> bool:
    """Whether ``packet`` is an upload WRITE (at Upload Offset, address 60), optionally
    the one for table ``offset``."""
    if len(packet) < 9 or packet[4] != 0x03 or packet[5] != 60:
        return False
    return offset is None or int.from_bytes(packet[6:8], "little") == offset


def is_commit(packet: bytes) -> bool:
    """Whether ``packet`` is the upload commit (WRITE of 7 bytes at Upload Length, 52)."""
    return len(packet) == 14 and packet[4] == 0x03 and packet[5] == 52


class CorruptOnce:
    """Flip one bit of the first packet that ``match`` accepts (byte ``position`` of it,
    default the last parameter byte), so its checksum fails and the device drops it."""

    def __init__(self, match: Callable[[bytes], bool], position: int = -2) -> None:
        self.match = match
        self.position = position
        self.done = False
        self.hit: int | None = None  # index of the damaged packet

    def __call__(self, index: int, packet: bytes) -> bytes | None:
        if self.done or not self.match(packet):
            return packet
        self.done, self.hit = True, index
        damaged = bytearray(packet)
        damaged[self.position] ^= 0x01
        return bytes(damaged)


class CutAfter:
    """The cable is pulled after the first packet that ``match`` accepts: it and those
    before it get through, nothing after it does (until the filter is removed)."""

    def __init__(self, match: Callable[[bytes], bool]) -> None:
        self.match = match
        self.cut = False
        self.dropped = 0

    def __call__(self, index: int, packet: bytes) -> bytes | None:
        if self.cut:
            self.dropped += 1
            return None
        if self.match(packet):
            self.cut = True
        return packet


# -- the pieces ---------------------------------------------------------------------------


class Framer:
    """Splits the host's byte stream into packets (FF FF ID LEN ... by LEN), so a line
    filter can act on whole packets. Bytes that are not a packet pass on unframed."""

    def __init__(self) -> None:
        self.buf = bytearray()
        self.since = 0.0  # when the oldest buffered byte arrived

    def feed(self, data: bytes, now: float) -> list[tuple[bool, bytes]]:
        """(is_packet, bytes) runs, in order."""
        if data and not self.buf:
            self.since = now
        self.buf += data
        out: list[tuple[bool, bytes]] = []
        buf = self.buf
        while buf:
            start = buf.find(b"\xff\xff")
            if start < 0:  # no header: pass it on, but a trailing FF may begin one
                cut = len(buf) - 1 if buf[-1] == 0xFF else len(buf)
            elif start > 0:
                cut = start
            elif len(buf) >= 3 and buf[2] == 0xFF:
                cut = 1  # FF FF FF: the header is the last two
            elif len(buf) >= 4 and buf[3] < 2:
                cut = 1  # no packet is this short
            else:
                cut = 0
            if cut:
                out.append((False, bytes(buf[:cut])))
                del buf[:cut]
                self.since = now
                continue
            if len(buf) < 4 or len(buf) < buf[3] + 4:
                break
            total = buf[3] + 4
            out.append((True, bytes(buf[:total])))
            del buf[:total]
            self.since = now
        return out

    def stale(self, now: float) -> bytes:
        """Buffered bytes that waited too long to become a packet (handed on as they are)."""
        if self.buf and now - self.since > PARTIAL_PACKET_S:
            data = bytes(self.buf)
            self.buf.clear()
            return data
        return b""


class PacedWire:
    """One direction of a UART: bytes leave at most one per ``10 / baud`` seconds."""

    def __init__(self, baudrate: float | None) -> None:
        self.period = byte_time(baudrate) if baudrate else 0.0
        self.queue: collections.deque[tuple[float, int]] = collections.deque()
        self.free_at = 0.0

    def put(self, data: bytes, now: float) -> None:
        t = max(now, self.free_at)
        for byte in data:
            t += self.period
            self.queue.append((t, byte))
        self.free_at = t

    def due(self, now: float) -> bytes:
        out = bytearray()
        queue = self.queue
        while queue and queue[0][0] <= now:
            out.append(queue.popleft()[1])
        return bytes(out)

    def next_due(self) -> float | None:
        return self.queue[0][0] if self.queue else None


TABLE_CAPACITY = lib.CTL_MAX_TABLE_BYTES
"""The emulated controller's Table Capacity: the largest board's (the CM-530's)."""
TABLE_ARENA = TABLE_CAPACITY * 3 // 2
"""Bytes of its table arena, laid out as the CM-530's (``BOARD_TABLE_ARENA``): an upload
lands on the active table, and is refused while it plays, once that is larger than half
the capacity (protocol/controller.md, "Where a table is staged")."""


class ControllerDevice:
    """One ``ctl_device`` in C memory with its bus side wired to ``bus`` (or to nothing),
    and a table arena of ``arena`` bytes holding tables of up to ``capacity``."""

    def __init__(
        self,
        bus: Bus | None = None,
        table: bytes | None = None,
        capacity: int = TABLE_CAPACITY,
        arena: int = TABLE_ARENA,
    ) -> None:
        self._mem = ffi.new("uint8_t[]", lib.ctl_device_bytes(arena))
        self.d = ffi.cast("ctl_device *", self._mem)
        lib.ctl_init(self.d)
        lib.ctl_set_tables(self.d, arena, capacity)
        self.bus = bus
        self._out = ffi.new("uint8_t[]", lib.CTL_PC_REPLY_MAX)
        self._out_len = ffi.new("size_t *")
        self._bus_out = ffi.new("uint8_t[]", lib.CTL_BUS_TX_MAX)
        self._reply_len = ffi.new("uint8_t *")
        if table is not None and not lib.ctl_load_table(self.d, table, len(table)):
            raise SimInputError("the initial table does not validate: write it with write_gait")
        lib.ctl_table_changed(self.d)

    def feed(self, data: bytes, now_ms: int) -> bytes:
        """Bytes from the PC link; returns the status packets the device sends back."""
        sent = bytearray()
        for byte in data:
            while not lib.ctl_pc_feed(self.d, byte):
                sent += self._poll(now_ms)
        sent += self._poll(now_ms)
        return bytes(sent)

    def _poll(self, now_ms: int) -> bytes:
        sent = bytearray()
        while lib.ctl_pc_poll(self.d, now_ms, self._out, lib.CTL_PC_REPLY_MAX, self._out_len):
            if self._out_len[0]:
                sent += ffi.buffer(self._out, self._out_len[0])
        return bytes(sent)

    def tick(self, now_ms: int) -> None:
        """One control tick, then this tick's bus transactions (in bus time)."""
        lib.ctl_tick(self.d, now_ms)
        bus = self.bus
        if bus is not None:
            bus.run_until(max(bus.now, now_ms / 1000.0))
        while True:
            n = lib.ctl_bus_next(self.d, self._bus_out, lib.CTL_BUS_TX_MAX, self._reply_len)
            if n == 0:
                return
            want = self._reply_len[0]
            if bus is None:
                if want:
                    lib.ctl_bus_rx_done(self.d)
                continue
            packet = bytes(ffi.buffer(self._bus_out, n))
            bus.master_flush_input()
            bus.master_write(packet)
            if want:
                deadline = bus.now + n * byte_time(bus.baudrate) + BUS_REPLY_TIMEOUT_S
                while bus.run_until_master_data(deadline):
                    chunk = bus.master_read(256)
                    if lib.ctl_bus_rx(self.d, chunk, len(chunk)):
                        break
                lib.ctl_bus_rx_done(self.d)

    @property
    def state(self) -> int:
        return lib.ctl_state(self.d)

    @property
    def error_flags(self) -> int:
        return lib.ctl_error_flags(self.d)

    def active_table(self) -> bytes:
        size = ffi.new("size_t *")
        ptr = lib.ctl_active_table(self.d, size)
        return b"" if ptr == ffi.NULL else bytes(ffi.buffer(ptr, size[0]))


class ControllerPty(ThreadedServer):
    """Serves a :class:`ControllerDevice` on a new pseudo-terminal from a thread.

    ``robot`` (a built-in name or TOML path) or ``servo_ids`` put emulated AX-12s on the
    device's bus (default: the snake5 robot's); ``bus`` gives a ready :class:`Bus`;
    ``robot=None`` with neither leaves the bus empty. ``baudrate``: pace the PC link at
    this rate (None: bytes pass as fast as the pty carries them). ``line_filter``: see
    :data:`LineFilter`; it may be replaced while serving (under :attr:`lock`).
    ``table``: the table the controller starts with (as if loaded from flash).
    """

    def __init__(
        self,
        *,
        robot: str | None = "snake5",
        servo_ids: tuple[int, ...] | None = None,
        bus: Bus | None = None,
        baudrate: float | None = None,
        line_filter: LineFilter | None = None,
        table: bytes | None = None,
        tick_ms: int = TICK_MS,
    ) -> None:
        if bus is None and (robot or servo_ids):
            options = SimOptions(robot=None if servo_ids else robot, ids=servo_ids)
            bus = options.build_bus(BUS_BAUD)
        self.bus = bus
        self.device_logic = ControllerDevice(bus, table)
        self.baudrate = baudrate
        self.line_filter = line_filter
        self.tick_ms = tick_ms
        self.host_packets: list[bytes] = []
        """Every packet the host sent, as it sent it (before the line filter)."""
        self.longest_tick_gap_s = 0.0
        """The longest time between two control ticks so far: ``tick_ms`` when the host
        kept the emulator on time, more when it held the serving thread up (ticks it
        could not run on time are skipped, as the servos then chase older goals)."""
        self.device = ""
        self._pty = RawPty()
        self._thread: ServerThread | None = None
        self._stopped = False

    # -- life cycle -------------------------------------------------------------------------

    def start(self) -> ControllerPty:
        self.device = self._pty.open()
        self._thread = ServerThread(f"snakebot.sim-controller {self.device}")
        self._thread.start(self._serve)
        return self

    @property
    def error(self) -> BaseException | None:
        """What stopped the serving thread, if it died."""
        return None if self._thread is None else self._thread.error

    def close(self) -> None:
        self._stopped = True
        self._stop_thread()
        self._pty.close()

    # -- looking in ---------------------------------------------------------------------------

    def active_table(self) -> bytes:
        with self.lock:
            return self.device_logic.active_table()

    def state(self) -> int:
        with self.lock:
            return self.device_logic.state

    # -- the loop ---------------------------------------------------------------------------

    def _serve(self) -> None:
        assert self._thread is not None
        thread = self._thread
        master, wake = self._pty.master, thread.wake_fd
        t0 = time.monotonic()
        framer = Framer()
        to_device = PacedWire(self.baudrate)
        to_host = PacedWire(self.baudrate)
        pending_out = bytearray()
        next_tick = 0.0
        last_tick: float | None = None
        while not self._stopped:
            now = time.monotonic() - t0
            now_ms = int(now * 1000) & 0xFFFFFFFF
            data = b""
            try:
                data = os.read(master, 4096)
            except BlockingIOError:
                pass
            except OSError:
                return  # the pty is gone
            with thread.lock:
                runs = framer.feed(data, now) if data else []
                stale = framer.stale(now)
                if stale:
                    runs.append((False, stale))
                for is_packet, run in runs:
                    if is_packet:
                        index = len(self.host_packets)
                        self.host_packets.append(run)
                        if self.line_filter is not None:
                            run = self.line_filter(index, run) or b""
                    to_device.put(run, now)
                arrived = to_device.due(now)
                if arrived:
                    to_host.put(self.device_logic.feed(arrived, now_ms), now)
                if now >= next_tick:
                    self.device_logic.tick(now_ms)
                    ticked = time.monotonic()  # `now` may be older: the lock was waited for
                    if last_tick is not None:
                        gap = ticked - last_tick
                        self.longest_tick_gap_s = max(self.longest_tick_gap_s, gap)
                    last_tick = ticked
                    next_tick += self.tick_ms / 1000.0
                    if next_tick <= now:
                        next_tick = now + self.tick_ms / 1000.0
            pending_out += to_host.due(now)
            if pending_out:
                try:
                    written = os.write(master, pending_out)
                    del pending_out[:written]
                except BlockingIOError:
                    pass
                except OSError:
                    return
            wakes = [next_tick] + [
                t for t in (to_device.next_due(), to_host.next_due()) if t is not None
            ]
            if framer.buf:
                wakes.append(framer.since + PARTIAL_PACKET_S)
            wait = max(MIN_WAKE_S, min(wakes) - (time.monotonic() - t0))
            if pending_out:
                wait = MIN_WAKE_S
            ready, _, _ = select.select([master, wake], [], [], wait)
            if wake in ready:
                return


def main(argv: list[str] | None = None) -> int:
    """``python -m snakebot.sim.controller_pty``: serve the controller until Ctrl-C."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m snakebot.sim.controller_pty",
        description="The snakebot controller's C device logic on a pseudo-terminal, driving "
        "emulated servos: point `snakebot upload/play/monitor --port` at the printed device.",
    )
    parser.add_argument("--robot", default="snake5", help="servos of this robot (default snake5)")
    parser.add_argument("--baud", type=float, help="pace the PC link at this baud rate")
    args = parser.parse_args(argv)
    with ControllerPty(robot=args.robot, baudrate=args.baud) as server:
        print(f"controller on {server.device} (Ctrl-C stops it)", flush=True)
        try:
            while server.running:
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
