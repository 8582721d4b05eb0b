"""Write the hand-made seed inputs of the fuzz targets into fuzz/corpus/<target>/seed-*.

    python fuzz/seeds.py            # (re)writes the seeds; the minimised corpus is kept

Seeds give the fuzzer a start deep inside the state space instead of at the door:

* fuzz_dxl_parser: every stream of the shared byte-exact vectors (protocol/vectors/*.json)
  under each delivery mode, and a few encoder round trips.
* fuzz_pclink: programs in the target's step language (see the comment at the top of
  fuzz/fuzz_pclink.c): a table uploaded and played with steering and speed changes; the
  serpenoid on a hand-written roster; every kind of damaged upload; the three ways into
  the safe state and out again; garbage, RESET, ID and Status Return Level changes.

The builders below mirror how fuzz_pclink.c reads its input, operand by operand; a seed
that drifts out of step is still a valid input, only a less useful one.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

HERE = Path(__file__).resolve().parent
VECTORS = HERE.parent / "protocol" / "vectors"

# fuzz_pclink step opcodes
(
    RAW,
    PACKET,
    WRITE,
    ROSTER,
    UPLOAD,
    COMMIT_STAGED,
    COMMAND,
    JOINTS,
    RESET,
    TICK,
    SEND,
    SCHEDULE,
    KNOB,
    ANSWER,
    POWER,
    LIBRARY,
    BUTTONS,
    PROGRAM,
) = range(18)
# instruction selectors of the PACKET step (its table of common instructions)
PING, READ, WRITE_I, SYNC_WRITE, RESET_I, REG_WRITE = range(6)
# commands
PLAY, SERPENOID, STOP, CLEAR, PROGRAM_RUN = 1, 2, 3, 4, 5
# KNOB registers, by index in the step's table
SPEED, STEERING, LOOP, AMPLITUDE, OMEGA, DELTA, PHI0, SAFE_ACTION, BUS_LOSS, ERROR_MASK, LINK = (
    range(11)
)
# LIBRARY step selectors (sel % 3) and the CM-530's buttons
LIB_PLAY, LIB_STORE, LIB_DELETE = range(3)
BUTTON_U, BUTTON_D, BUTTON_START = 1, 2, 16
# bus answers
SILENCE, REPLY, ECHO_REPLY, DAMAGED, OTHER_SERVO, RAW_BYTES = range(6)


def u16(v: int) -> bytes:
    return struct.pack("<H", v & 0xFFFF)


class Program:
    """A fuzz_pclink input, built step by step."""

    def __init__(self, start_ms: int = 0) -> None:
        self.b = bytearray(u16(start_ms >> 16))

    def raw(self, data: bytes) -> Program:
        self.b += bytes([RAW, len(data)]) + data
        return self

    def packet(self, inst: int, params: bytes = b"", to: str = "me", other_id: int = 7) -> Program:
        sel = {"me": 0, "broadcast": 180, "other": 220}[to]
        self.b += bytes([PACKET, sel])
        if to == "other":
            self.b.append(other_id)
        self.b += bytes([inst, len(params)]) + params
        return self

    def write(self, addr: int, data: bytes) -> Program:
        assert 1 <= len(data) <= 12
        self.b += bytes([WRITE, addr, len(data) - 1]) + data
        return self

    def roster(
        self, slot: int, page: int, sid: int, lo: int, hi: int, zero: int = 512, reverse: int = 0
    ) -> Program:
        self.b += bytes([ROSTER, slot, page, sid, reverse]) + bytes(6)
        self.b += u16(zero) + u16(lo) + u16(hi)
        return self

    def upload(
        self,
        joints: int = 3,
        frames: int = 4,
        period: int = 100,
        loop: bool = True,
        first_id: int = 1,
        fault: int = 0,
        where: int = 0,
        seed: int = 1,
    ) -> Program:
        self.b += bytes([UPLOAD, joints - 1, frames - 1]) + u16(period - 1)
        self.b += bytes([1 if loop else 0, first_id])
        for j in range(joints):
            self.b += u16(300 + 10 * j) + u16(700 - 10 * j)  # limits
        x = seed
        for _ in range(frames * joints):
            x = (x * 1103515245 + 12345) & 0x7FFFFFFF
            self.b += u16(x >> 8)
        self.b += bytes([fault, where, 0x11])  # damage, where, the bits flipped
        return self

    def program(self, fault: int = 0, where: int = 0) -> Program:
        """A program of three segments (periodic, serpenoid, table) on 3 joints with wide
        limits, small enough to pass the controller's checks (protocol/program.md)."""
        self.b += bytes([PROGRAM, 3 - 1, 3 - 1, 1, 2, 20 - 1, 1])  # joints, segments, ...
        for j in range(3):
            self.b += u16(200) + u16(824) + bytes([j % 2]) + u16(312)  # limits, zero 512
        self.b += bytes([2]) + bytes([0]) + u16(3142) + bytes([40 - 1])  # periodic
        self.b += bytes([1]) + u16(300) + u16(3142) + u16(1047) + u16(0) + bytes([40 - 1])
        self.b += bytes([0, 0, 2 - 1, 2 - 1])  # table: frames 0..1, twice
        for j in range(3):
            self.b += u16(50 * (1 - 2 * (j % 2))) + bytes([0])  # offset rate
            self.b += u16(200) + bytes([0]) + u16(100) + bytes([0])  # sine, cosine
        for f in range(2):
            self.b += b"".join(u16(300 + 20 * f + 5 * j) for j in range(3))  # 500.. ticks
        self.b += bytes([fault, where, 0x11])
        return self

    def commit_staged(self, length: int) -> Program:
        self.b += bytes([COMMIT_STAGED]) + u16(length)
        return self

    def command(self, cmd: int) -> Program:
        self.b += bytes([COMMAND, cmd])
        return self

    def joints(self, n: int) -> Program:
        self.b += bytes([JOINTS, n])
        return self

    def reset(self) -> Program:
        self.b.append(RESET)
        return self

    def tick(self, dt: int = 10) -> Program:
        self.b += bytes([TICK, dt]) if dt < 40 else bytes([TICK, 200]) + u16(dt)
        return self

    def _answer(
        self, how: int, position: int = 512, error: int = 0, flip: int = 5, raw: bytes = b""
    ) -> bytes:
        data = u16(position) + u16(0) + u16(0) + bytes([120, 40])
        return bytes([how]) + data + bytes([error, flip, 3, 5, len(raw)]) + raw

    def send(self) -> Program:
        """The device's next bus packet; a READ stays in flight."""
        self.b.append(SEND)
        return self

    def answer(self, how: int = REPLY, **kw: object) -> Program:
        """The reply (or not) to the READ in flight."""
        self.b += bytes([ANSWER]) + self._answer(how, **kw)
        return self

    def schedule(self, how: int = REPLY, **kw: object) -> Program:
        self.b += bytes([SCHEDULE]) + self._answer(how, **kw)
        return self

    def power_cycle(self, damage_flash: bool = False, where: int = 0) -> Program:
        self.b += bytes([POWER, 1 if damage_flash else 0, where, 0x40])
        return self

    def library(
        self, sel: int, slot: int = 0, name: bytes = b"walk", kind: int = 1, length: int = 0
    ) -> Program:
        """Pick ``slot`` on the Library page (with Store Name and Store Kind), then PLAY it,
        or commit ``length`` staged bytes into it, or delete it."""
        self.b += bytes([LIBRARY, sel, slot]) + name.ljust(16, b"\0") + bytes([kind - 1])
        if sel != LIB_PLAY:
            self.b += u16(length)
        return self

    def buttons(self, held: int, dt: int = 10) -> Program:
        self.b += bytes([BUTTONS, dt, held])
        return self

    def press(self, held: int) -> Program:
        """Hold buttons for the debounce time, then release them as long."""
        for b in (held, 0):
            for _ in range(4):
                self.buttons(b)
        return self

    def knob(self, which: int, value: int) -> Program:
        self.b += bytes([KNOB, which]) + u16(value)
        return self

    def run(self, ticks: int, how: int = REPLY, dt: int = 10, **kw: object) -> Program:
        for _ in range(ticks):
            self.tick(dt).schedule(how, **kw)
        return self


def long_chunk(at: int, fill: int, page: int = 19, to: int = 200) -> bytes:
    """A raw WRITE packet of one long upload chunk for the controller (ID ``to``): at
    Upload Offset (60) the offset, Upload Data's 64 bytes, Window Page = ``page`` (19:
    Upload Data 2, whose 126 window bytes continue the chunk), the window's bytes."""
    data = bytes((fill + 3 * i) & 0xFF for i in range(190))
    params = bytes([60]) + u16(at) + data[:64] + bytes([page]) + data[64:]
    body = bytes([to, len(params) + 2, 3]) + params
    return b"\xff\xff" + body + bytes([~sum(body) & 0xFF])


def pclink_seeds() -> dict[str, bytes]:
    s = {}
    s["play-table"] = (
        Program()
        .upload()
        .command(PLAY)
        .run(12)
        .knob(STEERING, 512)
        .run(6)
        .knob(STEERING, -512 & 0xFFFF)
        .run(6)
        .knob(SPEED, 1024)
        .run(6)
        .knob(LOOP, 0)
        .run(30, dt=35)  # past the table's end; the program stays within 128 steps
        .b
    )
    # 84 steps of 20 ms: the program ends (DONE) within the run
    s["run-program"] = Program().program().command(PROGRAM_RUN).run(190).b
    s["program-damaged"] = Program().program(fault=1, where=40).program(fault=2, where=70).b
    s["play-once-big-table"] = (
        Program().upload(joints=18, frames=5, period=20, loop=False).command(PLAY).run(20).b
    )
    p = Program()
    for k in range(3):
        p.roster(k, 0, k + 1, 400, 620, zero=512, reverse=k % 2)
    s["serpenoid"] = (
        p.joints(3)
        .command(SERPENOID)
        .run(10)
        .knob(AMPLITUDE, 2618)
        .knob(PHI0, 2618)
        .run(10)
        .knob(STEERING, 512)
        .run(10)
        .knob(OMEGA, -31416 & 0xFFFF)
        .run(10)
        .roster(1, 0, 2, 700, 300)
        .run(5)
        .b
    )
    p = Program()
    for fault in range(5):
        p.upload(fault=fault, where=1, seed=fault + 3)
    s["damaged-uploads"] = p.commit_staged(0).commit_staged(60).commit_staged(2048).b
    p = Program()
    # a damaged table sent whole: magic, version, joints, flags, period, frames, CRC,
    # then a joint's ID, reserved byte, limits, and a frame value (3 joints, 4 frames)
    for where in (0, 4, 5, 6, 8, 10, 12, 16, 17, 18, 20, 34):
        p.upload(fault=5, where=where).upload(fault=6, where=where)
    s["invalid-tables"] = p.b
    s["staging-end"] = (
        Program().write(60, bytes([0xF8, 0x07]) + bytes(range(10))).commit_staged(2048).b
    )
    s["long-chunks"] = (
        Program()
        .upload(joints=18, frames=5, period=20)
        .raw(long_chunk(0, 7))
        .raw(long_chunk(190, 9))
        .raw(long_chunk(2048 - 189, 3))  # one byte past the staging area: refused whole
        .raw(long_chunk(380, 5, page=16))  # the window on a read-only page: refused
        .commit_staged(380)
        .command(PLAY)
        .run(3)
        .b
    )
    s["power-cycles"] = (
        Program()
        .power_cycle()
        .upload()
        .command(PLAY)
        .run(3)
        .power_cycle()
        .command(PLAY)
        .run(3)
        .power_cycle(damage_flash=True, where=20)
        .command(PLAY)
        .run(2)
        .b
    )
    table_bytes = 16 + 3 * 6 + 4 * 3 * 2  # what upload() sends: 3 joints, 4 frames
    s["library"] = (
        Program()
        .upload()
        .library(LIB_STORE, 0, b"wave", length=table_bytes)
        .library(LIB_STORE, 1, b"bad\x01name", length=table_bytes)
        .library(LIB_STORE, 2, b"prog", kind=3, length=7)
        .upload(seed=2)
        .library(LIB_PLAY, 0)
        .run(3)
        .press(BUTTON_U)
        .press(BUTTON_START)
        .press(BUTTON_D)
        .press(BUTTON_START)
        .run(2)
        .power_cycle()
        .library(LIB_PLAY, 2)
        .library(LIB_DELETE, 0)
        .library(LIB_PLAY, 0)
        .library(LIB_PLAY, 3)
        .b
    )
    # sel 22: a store, in the background over 3 ticks; sel 20: a delete, likewise
    # (fuzz_pclink.c, case 15); an upload and a play meanwhile are refused STORE_BUSY,
    # and a power cut during the delete leaves the slot
    s["library-background"] = (
        Program()
        .upload()
        .library(22, 0, b"wave", length=table_bytes)
        .upload(seed=2)
        .library(LIB_PLAY, 0)
        .run(3)
        .library(LIB_PLAY, 0)
        .run(1)
        .library(20, 0)
        .power_cycle()
        .library(LIB_PLAY, 0)
        .run(1)
        .b
    )
    s["long-bus-garbage"] = (
        Program().upload().tick().send().answer(RAW_BYTES, raw=bytes(range(50, 113))).run(2).b
    )
    s["safe-servo-error"] = (
        Program()
        .upload()
        .command(PLAY)
        .run(3)
        .run(2, error=0x20)
        .schedule(REPLY)
        .command(PLAY)
        .command(CLEAR)
        .command(PLAY)
        .run(4)
        .b
    )
    s["safe-bus-loss"] = (
        Program()
        .upload()
        .command(PLAY)
        .run(3)
        .run(18, how=SILENCE)
        .command(CLEAR)
        .command(PLAY)
        .run(3)
        .knob(SAFE_ACTION, 0)
        .run(18, how=DAMAGED)
        .b
    )
    s["safe-link-loss"] = (
        Program().upload().knob(LINK, 1).command(PLAY).run(3).tick(200).schedule().run(3).b
    )
    s["bus-answers"] = (
        Program()
        .upload()
        .command(PLAY)
        .run(2, how=ECHO_REPLY)
        .run(2, how=DAMAGED, flip=9)
        .run(2, how=DAMAGED, flip=1)
        .run(2, how=OTHER_SERVO)
        .run(2, how=RAW_BYTES, raw=b"\xff\xff\xff\x01\x0a")
        .b
    )
    p = Program().upload()
    for addr in range(0, 256, 40):
        p.packet(READ, bytes([addr, 40]))
    p.packet(READ, bytes([255, 1])).packet(READ, bytes([0, 0])).packet(READ, bytes([0]))
    p.packet(PING, to="broadcast").packet(PING, to="other").packet(REG_WRITE, bytes([6, 1]))
    p.packet(SYNC_WRITE, bytes([6, 1, 200, 1, 7, 1]), to="broadcast")
    p.raw(b"\xff\xff\xc8\x04\x02\x00\x05\x00" + b"\x01\x02\xff\xff\xff\xff\xc8\x02\x01")
    p.reset().packet(PING)
    s["packets"] = p.b
    s["id-and-level"] = (
        Program()
        .write(3, bytes([17]))
        .packet(PING)
        .packet(PING, to="other", other_id=200)
        .write(4, bytes([0]))
        .packet(READ, bytes([0, 2]))
        .write(4, bytes([1]))
        .packet(READ, bytes([0, 2]))
        .reset()
        .packet(PING)
        .b
    )
    s["roster-change-mid-read"] = (
        Program()
        .upload()
        .tick()
        .send()
        .roster(0, 0, 9, 300, 700)
        .answer()
        .tick()
        .send()
        .joints(1)
        .answer(ECHO_REPLY)
        .run(3)
        .b
    )
    s["clock-wrap"] = Program(0xFFFF0000).upload().command(PLAY).run(10, dt=39).b
    return s


def parser_seeds() -> dict[str, bytes]:
    s = {}
    for name in ("streams", "instructions", "status"):
        doc = json.loads((VECTORS / f"{name}.json").read_text())
        for k, v in enumerate(doc["vectors"]):
            stream = bytes.fromhex(v["stream"])
            if not stream:
                continue
            s[f"{name}-{k}"] = bytes([k % 9, 0]) + stream  # poll every 1..8 bytes, or greedy
    packet = bytes.fromhex("ffff010201fb")
    s["greedy-run"] = bytes([0x08, 0]) + b"\x00" * 300 + packet * 60
    s["reset-mid-packet"] = bytes([0x10, 3]) + packet * 3
    s["round-trip"] = bytes([0xFF, 1, 3, 10]) + bytes(range(20))
    return s


def main() -> None:
    for target, seeds in (("fuzz_dxl_parser", parser_seeds()), ("fuzz_pclink", pclink_seeds())):
        out = HERE / "corpus" / target
        out.mkdir(parents=True, exist_ok=True)
        for old in out.glob("seed-*"):
            old.unlink()
        for name, data in seeds.items():
            (out / f"seed-{name}").write_bytes(data)
        print(f"{target}: {len(seeds)} seeds in {out.relative_to(HERE.parent)}")


if __name__ == "__main__":
    main()
