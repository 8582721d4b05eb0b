"""Firmware in the loop, on both emulated boards (the CM-530's image on the emulated
STM32F103RE, the qemu board's build under QEMU): the firmware's Dynamixel bus on emulated
servos (snakebot.sim), its PC link on a pseudo-terminal. A table uploaded through ordinary
WRITE packets is committed, played, and the virtual servos follow it; garbage on the PC
link does not disturb playback or the answers; STOP stops the servos.

Nothing here is timed: the machine may be slow. What is checked is where the servos went
(each reaches every extreme the table asks of it, and never leaves the table's limits),
that the controller's telemetry mirrors the emulated servos, and that the bus traffic
was clean (no timeouts, no corrupt replies)."""

from __future__ import annotations

import time
import zlib

import numpy as np
import pytest
from firmware_support import (
    BOARDS,
    CONTROLLER_ID,
    QEMU_DIR,
    Running,
    assert_healthy_bus,
    client,
    running,
    sections,
    symbols,
)

from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import Packet
from snakebot.link.controller import Command, ControllerErrors, State, UploadResult, load
from snakebot.sim.bus.bus import Bus
from snakebot.sim.servo.fast import VirtualServo

pytestmark = [pytest.mark.qemu, pytest.mark.slow]

IDS = (1, 2, 3)
LIMITS = ((300, 724), (300, 724), (300, 724))
FRAMES = np.array(
    [[512, 512, 512], [700, 380, 620], [512, 512, 512], [330, 690, 410]], dtype=np.uint16
)
PERIOD_MS = 400
REACH_TICKS = 25  # how close to a frame's goal counts as reaching it
CTL = load()


def reg(name: str) -> int:
    return CTL.register(name).address


@pytest.fixture(scope="module", params=BOARDS)
def rig(request, tmp_path_factory):
    """The board's firmware on three emulated servos; stopped after the module's tests."""
    bus = Bus([VirtualServo(i) for i in IDS])
    with running(request.param, tmp_path_factory.mktemp("fil"), bus=bus) as fw:
        yield fw


def positions(rig: Running) -> list[float]:
    with rig.lock:
        return rig.bus.positions(IDS)


def upload(c, blob: bytes) -> None:
    """The upload sequence: chunks into the staging area (offset + data in one WRITE,
    each acknowledged), then length, CRC and commit in one WRITE."""
    window = CTL.register("Upload Data").size
    for offset in range(0, len(blob), window):
        c.write(
            CONTROLLER_ID,
            reg("Upload Offset"),
            offset.to_bytes(2, "little") + blob[offset : offset + window],
        )
    c.write(
        CONTROLLER_ID,
        reg("Upload Length"),
        len(blob).to_bytes(2, "little") + zlib.crc32(blob).to_bytes(4, "little") + b"\x01",
    )


def wait_until(predicate, deadline_s: float, step_s: float = 0.05):
    end = time.monotonic() + deadline_s
    while not predicate():
        if time.monotonic() > end:
            return False
        time.sleep(step_s)
    return True


def test_plays_an_uploaded_table_and_the_virtual_servos_follow(rig):
    table = GaitTable(IDS, PERIOD_MS, True, LIMITS, FRAMES, {})
    blob = table.encode()
    with client(rig.pc_link) as c:
        assert wait_until(lambda: _answers(c), 10)
        upload(c, blob)
        assert c.read_u8(CONTROLLER_ID, reg("Upload Result")) == UploadResult.OK
        assert c.read(CONTROLLER_ID, reg("Table CRC"), 4) == zlib.crc32(blob).to_bytes(4, "little")
        assert c.read_u8(CONTROLLER_ID, reg("Joint Count")) == len(IDS)
        c.write_u8(CONTROLLER_ID, reg("Command"), Command.PLAY)
        assert c.read_u8(CONTROLLER_ID, reg("State")) == State.PLAYING

        # Follow the table (up to three loops), sampling the emulated servos and the
        # frame being played, until every frame was seen and every extreme reached.
        seen = []
        frames_seen: set[int] = set()
        garbage = bytes(range(0, 200, 7))
        end = time.monotonic() + 3 * len(FRAMES) * PERIOD_MS / 1000 + 2.0
        done = False
        while time.monotonic() < end and not done:
            seen.append(positions(rig))
            frames_seen.add(c.read_u16(CONTROLLER_ID, reg("Play Frame")))
            c.port.write(garbage)  # noise on the PC link while it plays
            time.sleep(0.12)  # past the 100 ms inter-byte gap, so the noise is dropped
            assert c.ping(CONTROLLER_ID) == Packet(CONTROLLER_ID, 0, b"")
            done = _reached_all_extremes(np.array(seen)) and frames_seen >= {0, 1, 2, 3}
        seen_arr = np.array(seen)
        span = f"min {seen_arr.min(0)}, max {seen_arr.max(0)}"
        assert _reached_all_extremes(seen_arr), f"servos missed the table's extremes: {span}"
        lo = np.array([lo for lo, _ in LIMITS]) - 2
        hi = np.array([hi for _, hi in LIMITS]) + 2
        assert (seen_arr >= lo).all() and (seen_arr <= hi).all()  # clamped to the table's limits
        assert frames_seen >= {0, 1, 2, 3}  # every frame was played

        # The controller's telemetry mirrors the emulated servos.
        c.write_u8(CONTROLLER_ID, reg("Window Page"), 0)
        window = c.read(CONTROLLER_ID, CTL.servo_window_address, CTL.servo_record_size * len(IDS))
        records = CTL.decode_servo_window(window)
        assert [r["ID"] for r in records] == list(IDS)
        now = positions(rig)
        for r, p in zip(records, now, strict=True):
            assert abs(r["Present Position"] - p) < 120  # fresh within a few ticks of motion

        # Clean bus: every telemetry READ answered.
        assert_healthy_bus(
            c.read_u16(CONTROLLER_ID, reg("Bus Reads")),
            c.read_u16(CONTROLLER_ID, reg("Bus Timeouts")),
        )
        assert c.read_u16(CONTROLLER_ID, reg("Bus Errors")) == 0
        assert c.read_u16(CONTROLLER_ID, reg("Error Flags")) == 0

        # STOP: the controller goes idle and the servos come to rest.
        c.write_u8(CONTROLLER_ID, reg("Command"), Command.STOP)
        assert c.read_u8(CONTROLLER_ID, reg("State")) == State.IDLE
        assert wait_until(lambda: _at_rest(rig), 5)


def _answers(c) -> bool:
    try:
        return c.ping(CONTROLLER_ID, retries=0).id == CONTROLLER_ID
    except Exception:  # noqa: BLE001 - still booting
        return False


def _reached_all_extremes(seen: np.ndarray) -> bool:
    want_hi = FRAMES.max(0).astype(float)
    want_lo = FRAMES.min(0).astype(float)
    return bool(
        (seen.max(0) >= want_hi - REACH_TICKS).all()
        and (seen.min(0) <= want_lo + REACH_TICKS).all()
    )


def _at_rest(rig) -> bool:
    a = positions(rig)
    time.sleep(0.2)
    b = positions(rig)
    return max(abs(x - y) for x, y in zip(a, b, strict=True)) < 1.0


def test_a_failed_upload_leaves_the_old_table_active(rig):
    good = GaitTable(IDS, PERIOD_MS, True, LIMITS, FRAMES, {}).encode()
    other = GaitTable(IDS, PERIOD_MS, False, LIMITS, FRAMES[::-1].copy(), {}).encode()
    with client(rig.pc_link) as c:
        assert wait_until(lambda: _answers(c), 10)
        upload(c, good)
        assert c.read_u8(CONTROLLER_ID, reg("Upload Result")) == UploadResult.OK
        corrupted = other[:20] + bytes([other[20] ^ 0xFF]) + other[21:]
        window = CTL.register("Upload Data").size
        for offset in range(0, len(corrupted), window):
            data = offset.to_bytes(2, "little") + corrupted[offset : offset + window]
            c.write(CONTROLLER_ID, reg("Upload Offset"), data)
        commit = len(other).to_bytes(2, "little") + zlib.crc32(other).to_bytes(4, "little")
        c.write(CONTROLLER_ID, reg("Upload Length"), commit + b"\x01")  # CRC of the intended
        assert c.read_u8(CONTROLLER_ID, reg("Upload Result")) == UploadResult.TRANSFER_CRC
        assert c.read_u16(CONTROLLER_ID, reg("Error Flags")) & ControllerErrors.UPLOAD_CRC
        assert c.read(CONTROLLER_ID, reg("Table CRC"), 4) == zlib.crc32(good).to_bytes(4, "little")


STACK_PAINT = 0x5AC3A55A
RAM_END = 0x20002000


@pytest.mark.parametrize("rig", ["qemu"], indirect=True)
def test_stack_stays_within_its_reserve(rig):
    """Run after the playing test: the start-up code painted the free RAM; the deepest
    the stack has reached is where the paint ends. The qemu build's symbols and QEMU's
    monitor: the CM-530's own is tests/firmware/test_cm530_board.py's."""
    fw = rig.firmware
    syms = symbols(QEMU_DIR / "firmware.elf")
    bottom = syms["_ebss"]
    raw = fw.read(bottom, RAM_END - bottom)
    values = [int.from_bytes(raw[i : i + 4], "little") for i in range(0, len(raw), 4)]
    untouched = next((i for i, v in enumerate(values) if v != STACK_PAINT), len(values))
    used = RAM_END - (bottom + 4 * untouched)
    reserve = sections(QEMU_DIR / "firmware.elf")[".stack"][1]
    print(f"qemu board stack high-water mark: {used} of {reserve} bytes reserved")
    assert untouched > 0, "the stack reached .bss"
    assert used <= reserve
