"""Helpers for the controller-core tests: gait-table strategies, the C core's validator,
and a ctl_device driven with raw Protocol 1.0 bytes (through snakebot.core)."""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

from snakebot.core import ffi, lib
from snakebot.facts import devices
from snakebot.formats.gaittable import GaitTable, max_frames
from snakebot.formats.protocol import (
    BROADCAST_ID,
    Instruction,
    PacketParser,
    ping,
    read,
    status,
    write,
)
from snakebot.link.controller import chunk_writes
from snakebot.link.controller import load as load_controller
from snakebot.sim.controller_pty import TABLE_ARENA, TABLE_CAPACITY

CTL = load_controller()
CTL_ID = CTL.default_id
TICK_LOW, TICK_HIGH = devices.ax12().require_position().range


@st.composite
def gait_tables(draw: st.DrawFn, max_joints: int = 6, loop: bool | None = None) -> GaitTable:
    """Valid tables that fit the controller."""
    joints = draw(st.integers(1, max_joints))
    ids = draw(st.lists(st.integers(0, 253), min_size=joints, max_size=joints, unique=True))
    limits = []
    for _ in range(joints):
        lo = draw(st.integers(TICK_LOW, TICK_HIGH))
        limits.append((lo, draw(st.integers(lo, TICK_HIGH))))
    frames = draw(st.integers(1, min(max_frames(joints), 40)))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    lo = np.array([a for a, _ in limits])
    hi = np.array([b for _, b in limits])
    values = rng.integers(lo, hi + 1, size=(frames, joints))
    period = draw(st.integers(1, 65535))
    looped = draw(st.booleans()) if loop is None else loop
    return GaitTable(tuple(ids), period, looped, tuple(limits), values, {"seed": seed})


def c_validate(data: bytes) -> tuple[int, object]:
    """gt_validate() on data: (status, gt_info)."""
    info = ffi.new("gt_info *")
    buf = ffi.from_buffer(data) if data else ffi.NULL
    return lib.gt_validate(buf, len(data), info), info


def with_crc(data: bytes) -> bytes:
    """data with its table CRC recomputed (so a deliberate layout fault is what is left)."""
    data = bytearray(data)
    crc = zlib.crc32(bytes(data[16:]), zlib.crc32(bytes(data[:12])))
    data[12:16] = crc.to_bytes(4, "little")
    return bytes(data)


@dataclass
class Reply:
    id: int
    error: int
    params: bytes


class Device:
    """A ctl_device in C memory, spoken to in Protocol 1.0 bytes."""

    def __init__(self, capacity: int = TABLE_CAPACITY, arena: int = TABLE_ARENA) -> None:
        self._mem = ffi.new("uint8_t[]", lib.ctl_device_bytes(arena))
        self.d = ffi.cast("ctl_device *", self._mem)
        lib.ctl_init(self.d)
        lib.ctl_set_tables(self.d, arena, capacity)
        self._out = ffi.new("uint8_t[]", lib.CTL_PC_REPLY_MAX)
        self._len = ffi.new("size_t *")
        self.now = 0

    # -- PC link --------------------------------------------------------------------------
    def feed(self, data: bytes) -> bytes:
        """Feed bytes as the UART would; the bytes the device sends back."""
        sent = bytearray()
        for byte in data:
            assert lib.ctl_pc_feed(self.d, byte)
            while lib.ctl_pc_poll(self.d, self.now, self._out, lib.CTL_PC_REPLY_MAX, self._len):
                sent += ffi.buffer(self._out, self._len[0])
        return bytes(sent)

    def transact(self, packet: bytes) -> list[Reply]:
        """Send one packet; the status packets that came back."""
        events = PacketParser().feed(self.feed(packet))
        replies = []
        for ev in events:
            assert not hasattr(ev, "reason"), f"corrupt reply {ev}"
            replies.append(Reply(ev.id, ev.code, ev.params))
        return replies

    def one(self, packet: bytes) -> Reply:
        replies = self.transact(packet)
        assert len(replies) == 1, replies
        return replies[0]

    def read(self, address: int, length: int, id: int = CTL_ID) -> bytes:
        r = self.one(read(id, address, length))
        assert r.error == 0, f"READ {address}+{length}: error {r.error}"
        return r.params

    def get(self, name: str) -> int:
        reg = CTL.register(name)
        return reg.decode(self.read(reg.address, reg.size))

    def set(self, name: str, value: int) -> int:
        """WRITE a register; returns the status packet's error byte."""
        reg = CTL.register(name)
        data = int(value).to_bytes(reg.size, "little", signed=reg.signed)
        return self.one(write(CTL_ID, reg.address, data)).error

    def servo_window(self, page: int = 0) -> list[dict[str, int]]:
        assert self.set("Window Page", page) == 0
        size = CTL.servo_records * CTL.servo_record_size
        return CTL.decode_servo_window(self.read(CTL.servo_window_address, size))

    def upload(self, table: bytes, chunk: int = 64, commit: bool = True) -> int:
        """Upload through the window (snakebot.link.controller's WRITEs), then commit; returns
        Upload Result."""
        for address, payload in chunk_writes(table, chunk):
            assert self.one(write(CTL_ID, address, payload)).error == 0
        if commit:
            self.commit(len(table), zlib.crc32(table))
        return self.get("Upload Result")

    def commit(self, length: int, crc: int) -> int:
        start = CTL.register("Upload Length").address
        payload = length.to_bytes(2, "little") + crc.to_bytes(4, "little") + b"\x01"
        return self.one(write(CTL_ID, start, payload)).error

    def command(self, name: str) -> int:
        return self.set("Command", lib_value("Command", name))

    # -- control tick and bus ---------------------------------------------------------------
    def tick(self, now: int, replies: dict[int, bytes] | None = None) -> list[bytes]:
        """One control tick at `now` ms; READs are answered from `replies` (servo ID ->
        bytes the bus returns; missing = timeout). Returns the packets put on the bus."""
        self.now = now
        lib.ctl_tick(self.d, now)
        out = ffi.new("uint8_t[]", lib.CTL_BUS_TX_MAX)
        reply_len = ffi.new("uint8_t *")
        sent = []
        while True:
            n = lib.ctl_bus_next(self.d, out, lib.CTL_BUS_TX_MAX, reply_len)
            if n == 0:
                return sent
            packet = bytes(ffi.buffer(out, n))
            sent.append(packet)
            if reply_len[0]:
                answer = (replies or {}).get(packet[2], b"")
                if answer:
                    lib.ctl_bus_rx(self.d, answer, len(answer))
                lib.ctl_bus_rx_done(self.d)

    @property
    def state(self) -> int:
        return lib.ctl_state(self.d)

    @property
    def flags(self) -> int:
        return lib.ctl_error_flags(self.d)


def lib_value(enum: str, name: str) -> int:
    return CTL.enums[enum][name]


def telemetry_reply(
    servo_id: int,
    position: int = 512,
    error: int = 0,
    speed: int = 0,
    load: int = 0,
    voltage: int = 120,
    temperature: int = 35,
) -> bytes:
    """The status packet an AX-12 sends for READ 36..43."""
    data = (
        position.to_bytes(2, "little")
        + speed.to_bytes(2, "little")
        + load.to_bytes(2, "little")
        + bytes([voltage, temperature])
    )
    return status(servo_id, error, data)


__all__ = [
    "BROADCAST_ID",
    "CTL",
    "CTL_ID",
    "Device",
    "Instruction",
    "Reply",
    "c_validate",
    "gait_tables",
    "lib_value",
    "ping",
    "telemetry_reply",
    "with_crc",
]
