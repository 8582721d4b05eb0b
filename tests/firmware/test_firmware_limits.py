"""The servos enforce the robot's limits (issue #17): the firmware on either board (the
CM-530's image on the emulated chip, the qemu board's build under QEMU), on an emulated
bus of three AX-12s, makes each servo's CW/CCW Angle Limit equal to the robot's limits
set from the host, writing the servo's EEPROM only where it differs and reading it back;
refuses tables that reach beyond those limits; and will not move while a servo has not
taken them. Under bus corruption no servo accepts a goal outside them (the campaigns
``servo-limits-*`` in tests/reliability/test_reliability_campaigns.py, on QEMU;
``python -m tests.reliability.rig.campaigns --only servo-limits-5pct --seconds 120`` for
the long run). The limits kept in flash come
back after a power cycle of the CM-530's image on the emulated chip (the qemu board keeps
them in RAM only)."""

from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import pytest
from controller_cli_support import cli, cli_json, save, wave_table
from ctl_support import CTL, CTL_ID, Device, ffi, lib
from firmware_support import (
    APP_BASE,
    BOARDS,
    Running,
    board_value,
    build_firmware,
    running,
)

from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import read, status, write
from snakebot.formats.upload_writes import chunk_writes, commit_write
from snakebot.link.controller import Command, ControllerErrors, LimitsState, State, UploadResult
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.limits import (
    LimitsError,
    encode_limits,
    limits_state,
    set_limits,
    wait_settled,
)
from snakebot.model.robots import load_robot
from snakebot.model.robots.model import TORQUE_LIMIT
from snakebot.sim.bus.bus import Bus
from snakebot.sim.bus.faults import FaultConfig
from snakebot.sim.servo.fast import VirtualServo
from tests.reliability.rig.campaigns import FRAMES, IDS, LIMITS, PERIOD_MS, gait_table
from tests.reliability.rig.campaigns.rig import PC_RETRIES
from tests.reliability.rig.campaigns.taps import AuditedServo

# QEMU paces the PC link at 57600 baud in software, and the emulated CM-530 runs in the
# tests' own process: beside a CPU-bound suite on a 2-core machine their replies can miss
# the client's deadline, so these are `serial` (run apart from the rest of the suite).
pytestmark = [pytest.mark.qemu, pytest.mark.serial]

ROBOT = dict(zip(IDS, LIMITS, strict=True))
FACTORY = (0, 1023)  # an AX-12's angle limits as shipped


@pytest.fixture(scope="module", autouse=True)
def firmware() -> None:
    build_firmware()


class Rig:
    """What these tests use of the reliability campaigns' rig (tests/reliability/rig), on
    either board: the firmware running on a bus of three audited AX-12s (each counts the
    WRITEs that reached its angle limits), a controller client on its PC link, and the
    upload sequence. Read the bus holding :attr:`lock`."""

    def __init__(self, fw: Running, servos: list[AuditedServo], ctl: ControllerClient) -> None:
        self.bus = fw.bus
        self.lock = fw.lock
        self.servos = servos
        self.ctl = ctl

    def write(self, values: dict[str, int]) -> None:
        self.ctl.write(values)

    def command(self, cmd: Command) -> None:
        self.ctl.command(cmd.name)

    def upload(self, blob: bytes) -> int:
        """The upload sequence; returns Upload Result."""
        return _upload(self.ctl, blob)


@pytest.fixture(params=BOARDS)
def rig(request, tmp_path) -> Iterator[Rig]:
    servos = [AuditedServo(i, lim) for i, lim in zip(IDS, LIMITS, strict=True)]
    bus = Bus(servos, faults=FaultConfig(seed=1))
    with (
        running(request.param, tmp_path, bus=bus) as fw,
        # The campaigns' retries: a busy host may delay a reply past the margin.
        ControllerClient.open(fw.pc_link, retries=PC_RETRIES) as ctl,
    ):
        yield Rig(fw, servos, ctl)


def preset(rig: Rig, servo_id: int, limits: tuple[int, int]) -> None:
    """Give a servo these angle limits in its EEPROM, as a previous run would have."""
    with rig.lock:
        servo = rig.bus.servo(servo_id)
        servo.set_register("CW Angle Limit", limits[0])
        servo.set_register("CCW Angle Limit", limits[1])


def held(rig: Rig) -> list[tuple[int, int]]:
    with rig.lock:
        return [s.angle_limits() for s in rig.servos]


def writes(rig: Rig) -> list[int]:
    with rig.lock:
        return [s.angle_limit_writes for s in rig.servos]


def settled(rig: Rig, timeout_s: float = 10.0) -> str:
    return wait_settled(rig.ctl, timeout_s)[0]


def test_servos_take_the_robot_limits_written_only_where_they_differ(rig):
    preset(rig, 1, LIMITS[0])  # servo 1 holds them already; 2 and 3 are as shipped
    assert held(rig) == [LIMITS[0], FACTORY, FACTORY]
    assert limits_state(rig.ctl) == ("NONE", 0)

    report = set_limits(rig.ctl, ROBOT)

    assert (report.state, report.count) == ("VERIFIED", 3)
    assert held(rig) == list(LIMITS)
    assert writes(rig) == [0, 1, 1]  # one EEPROM write each where they differed, none else
    # a new roster (the table's commit) checks them again: read, equal, nothing written
    assert rig.upload(gait_table()) == UploadResult.OK
    assert settled(rig) == "VERIFIED"
    assert writes(rig) == [0, 1, 1]
    # a servo whose limits were changed behind the controller's back (say, swapped for a
    # spare) is put right at the next roster change: here, empty the roster and restore it
    preset(rig, 3, FACTORY)
    rig.write({"Joint Count": 0})
    rig.write({"Joint Count": 3})
    assert settled(rig) == "VERIFIED"
    assert held(rig) == list(LIMITS)
    assert writes(rig) == [0, 1, 2]
    # and it plays
    rig.command(Command.PLAY)
    assert rig.ctl.read("State")["State"] == State.PLAYING
    # while it plays, the controller keeps re-reading the servos' angle limits (a damaged
    # packet could change them): one changed is written back, with no roster change
    preset(rig, 2, FACTORY)
    deadline = time.monotonic() + 10
    while held(rig) != list(LIMITS) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert held(rig) == list(LIMITS)
    assert writes(rig) == [0, 2, 2]
    assert settled(rig) == "VERIFIED"


def torques(rig: Rig) -> list[int]:
    with rig.lock:
        return [s.regs.get("Torque Limit") for s in rig.servos]


def test_servos_take_the_robot_torque_limit_and_get_it_back_after_a_power_cycle(rig):
    torque = TORQUE_LIMIT.from_units(60.0)  # 60 % of stall torque
    full = TORQUE_LIMIT.value_range()[1]
    with rig.lock:
        rig.servos[0].set_register("Torque Limit", torque)  # servo 1 holds it already
    assert torques(rig) == [torque, full, full]

    report = set_limits(rig.ctl, ROBOT, torque=torque)

    assert (report.state, report.count, report.torque_limit) == ("VERIFIED", 3, torque)
    assert torques(rig) == [torque] * 3
    assert held(rig) == list(LIMITS)
    # while it plays, a servo that lost power (Torque Limit back to Max Torque) is found
    # by the audit and written again; its angle limits (EEPROM) were kept: not rewritten
    assert rig.upload(gait_table()) == UploadResult.OK
    assert settled(rig) == "VERIFIED"
    rig.command(Command.PLAY)
    assert rig.ctl.read("State")["State"] == State.PLAYING
    eeprom_writes = writes(rig)
    with rig.lock:
        servo = rig.servos[2]
        servo.power_off(servo.t)
        servo.power_on(servo.t)
    assert torques(rig)[2] == full
    deadline = time.monotonic() + 20
    while torques(rig) != [torque] * 3 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert torques(rig) == [torque] * 3
    assert writes(rig) == eeprom_writes
    assert settled(rig) == "VERIFIED"
    # limits set again without a torque limit leave the servos' Torque Limit alone
    assert set_limits(rig.ctl, ROBOT).torque_limit is None
    assert torques(rig) == [torque] * 3


def test_a_table_wider_than_the_robot_limits_is_refused(rig):
    set_limits(rig.ctl, ROBOT)
    assert rig.upload(gait_table()) == UploadResult.OK
    before = rig.ctl.read("Table Size", "Table CRC")
    wide = tuple((lo - 100, hi + 100) for lo, hi in LIMITS)  # e.g. +-145 deg vs the robot's
    frames = FRAMES.copy()
    frames[0] = [hi + 100 for _, hi in LIMITS]
    table = GaitTable(IDS, PERIOD_MS, True, wide, frames, {}).encode()
    assert rig.upload(table) == UploadResult.OUTSIDE_ROBOT_LIMITS
    after = rig.ctl.read("Table Size", "Table CRC", "Error Flags")
    assert after["Error Flags"] & ControllerErrors.UPLOAD_LAYOUT
    assert (after["Table Size"], after["Table CRC"]) == (before["Table Size"], before["Table CRC"])
    # a servo the robot's limits do not cover is refused too
    other = GaitTable((1, 2, 9), PERIOD_MS, True, LIMITS, FRAMES, {}).encode()
    assert rig.upload(other) == UploadResult.OUTSIDE_ROBOT_LIMITS
    # narrower limits set after the table: the old table may not play any more
    set_limits(rig.ctl, {sid: (lo + 50, hi - 50) for sid, (lo, hi) in ROBOT.items()})
    rig.command(Command.PLAY)
    r = rig.ctl.read("State", "Error Flags")
    assert r["State"] == State.IDLE and r["Error Flags"] & ControllerErrors.REFUSED


def test_malformed_robot_limits_are_refused(rig):
    with pytest.raises(LimitsError, match="BAD_ROBOT_LIMITS"):
        set_limits(rig.ctl, {1: (700, 300)})
    assert limits_state(rig.ctl) == ("NONE", 0)


def test_a_servo_that_will_not_take_them_stops_the_controller_from_moving(rig):
    assert rig.upload(gait_table()) == UploadResult.OK
    with rig.lock:
        rig.bus.servo(2).set_register("Lock", 1)  # EEPROM writes refused until power-off
    with pytest.raises(LimitsError, match="FAILED"):
        set_limits(rig.ctl, ROBOT, timeout_s=20.0)
    assert held(rig)[1] == FACTORY
    assert rig.ctl.read("Limits State")["Limits State"] == LimitsState.FAILED
    assert rig.ctl.read("Error Flags")["Error Flags"] & ControllerErrors.LIMITS
    rig.command(Command.PLAY)
    r = rig.ctl.read("State", "Error Flags")
    assert r["State"] == State.IDLE and r["Error Flags"] & ControllerErrors.REFUSED
    # unlocked (power-cycled), CLEAR checks again, and it may move
    with rig.lock:
        rig.bus.servo(2).set_register("Lock", 0)
    rig.command(Command.CLEAR)
    assert settled(rig, 20.0) == "VERIFIED"
    assert held(rig) == list(LIMITS)
    rig.command(Command.PLAY)
    assert rig.ctl.read("State")["State"] == State.PLAYING


@pytest.mark.parametrize("board", BOARDS)
def test_limits_set_from_the_robot_file_then_a_wider_table_is_refused(board, tmp_path):
    """`snakebot limits set snake5`, then a table made for +-145 degree joints on the same
    servo IDs: refused by the controller with the reason and the fix; snake5's own
    table is taken."""
    robot = load_robot("snake5")
    wanted = [tuple(lim) for lim in robot.tick_limits]
    with running(board, tmp_path) as fw:
        port, bus = fw.pc_link, fw.bus
        assert cli_json("limits", "show", "--port", port) == {
            "state": "NONE",
            "count": 0,
            "torque_limit": None,
            "torque_limit_percent": None,
        }
        report = cli_json("limits", "set", "snake5", "--port", port)
        assert (report["state"], report["count"]) == ("VERIFIED", len(wanted))
        with fw.lock:
            held = [
                (bus.servo(i).regs.get("CW Angle Limit"), bus.servo(i).regs.get("CCW Angle Limit"))
                for i in robot.servo_ids
            ]
        assert held == wanted
        shown = cli_json("limits", "show", "--port", port)
        assert shown == {
            "state": "VERIFIED",
            "count": len(wanted),
            "torque_limit": None,
            "torque_limit_percent": None,
        }

        # +-145 degrees (24..1000) on the same servos, goals out to 896 and 198
        wave = wave_table(robot.servo_ids)
        frames = np.array(wave.frames)
        frames[0], frames[1] = 896, 198
        wide = GaitTable(wave.joint_ids, 20, True, ((24, 1000),) * len(wanted), frames, {})
        result = cli("upload", save(wide, tmp_path, "wide.gait"), "--port", port)
        assert result.exit_code == 2, result.output  # refused: the table is bad input
        assert "OUTSIDE_ROBOT_LIMITS" in result.stderr and "limits set" in result.stderr
        own = GaitTable(wave.joint_ids, 20, True, tuple(wanted), wave.frames, {})
        assert cli_json("upload", save(own, tmp_path), "--port", port)["bytes"] > 0
        # at once after the upload (a new roster: the servos are being checked) play waits
        assert cli_json("play", "--port", port)["state"] == "PLAYING"


def test_the_limits_kept_in_flash_come_back_as_they_were_set():
    """What the firmware stores after a LIMITS commit (ctl_robot_limits) is what it loads
    at start (ctl_load_limits) on a fresh controller: the same limits, and a table beyond
    them refused as before; a malformed record is not loaded."""
    first = Device()
    blob = encode_limits(ROBOT)
    for address, data in chunk_writes(blob, controller=CTL):
        assert first.one(write(CTL_ID, address, data)).error == 0
    assert first.one(write(CTL_ID, *commit_write(blob, CTL, what="LIMITS"))).error == 0
    assert first.get("Upload Result") == UploadResult.OK
    assert lib.ctl_limits_changed(first.d) and not lib.ctl_limits_changed(first.d)
    out = ffi.new("uint8_t[]", 128)
    kept = bytes(ffi.buffer(out, lib.ctl_robot_limits(first.d, out, 128)))
    assert kept == blob

    after_reset = Device()
    assert lib.ctl_load_limits(after_reset.d, kept, len(kept))
    assert after_reset.get("Limits Count") == len(ROBOT)
    assert after_reset.get("Limits State") == LimitsState.APPLYING  # the servos are checked
    wide = tuple((lo - 1, hi) for lo, hi in LIMITS)
    assert after_reset.upload(GaitTable(IDS, PERIOD_MS, True, wide, FRAMES, {}).encode()) == (
        UploadResult.OUTSIDE_ROBOT_LIMITS
    )
    assert after_reset.upload(gait_table()) == UploadResult.OK
    assert not lib.ctl_load_limits(Device().d, kept[:-1], len(kept) - 1)


def _upload(ctl: ControllerClient, blob: bytes) -> int:
    """The upload sequence through ``ctl``; returns Upload Result."""
    for address, data in chunk_writes(blob, controller=CTL):
        ctl.write_block(address, data)
    ctl.write_block(*commit_write(blob, CTL))
    return ctl.read("Upload Result")["Upload Result"]


def _servos_as_shipped() -> Bus:
    return Bus([VirtualServo(i) for i in IDS])


def test_the_limits_kept_in_flash_come_back_after_a_power_cycle_of_the_cm530(tmp_path):
    """The same on the CM-530's image on the emulated chip (the qemu board keeps its limits
    in RAM only): limits set over the PC link are in its flash as they were sent; powered
    off and on (a new chip with that flash), it has them again, puts them into servos
    that lost them (swapped while it was off), refuses a table beyond them and takes one
    within; a damaged record in the flash is not loaded."""
    blob = encode_limits(ROBOT)
    with running("cm530", tmp_path, bus=_servos_as_shipped()) as fw:
        with ControllerClient.open(fw.pc_link) as ctl:
            assert set_limits(ctl, ROBOT).state == "VERIFIED"
            assert limits_state(ctl) == ("VERIFIED", len(ROBOT))
        flash = fw.flash()
    store = board_value("cm530", "BOARD_LIMITS_STORE_BASE") - APP_BASE
    size = board_value("cm530", "BOARD_LIMITS_STORE_SIZE")
    at = flash.find(blob, store, store + size)
    assert at >= 0, "the limits sent are not in the limits' store"

    bus = _servos_as_shipped()
    with running("cm530", tmp_path, bus=bus, image=flash) as fw:
        with ControllerClient.open(fw.pc_link) as ctl:
            assert wait_settled(ctl, 20.0) == ("VERIFIED", len(ROBOT))
            with fw.lock:
                held = [
                    (s.regs.get("CW Angle Limit"), s.regs.get("CCW Angle Limit"))
                    for s in bus.servos
                ]
            assert held == list(LIMITS)
            wide = tuple((lo - 1, hi) for lo, hi in LIMITS)
            table = GaitTable(IDS, PERIOD_MS, True, wide, FRAMES, {}).encode()
            assert _upload(ctl, table) == UploadResult.OUTSIDE_ROBOT_LIMITS
            assert _upload(ctl, gait_table()) == UploadResult.OK

    damaged = bytearray(flash)
    damaged[at + 2] ^= 0x01  # a servo's limit, one bit
    with running("cm530", tmp_path, bus=_servos_as_shipped(), image=bytes(damaged)) as fw:
        with ControllerClient.open(fw.pc_link) as ctl:
            assert limits_state(ctl) == ("NONE", 0)


def _bus_with_limits(ids: list[int], mins: list[int], maxs: list[int]):
    mem = ffi.new("uint8_t[]", lib.bus_master_size())
    b = ffi.cast("bus_master *", mem)
    lib.bus_init(b)
    lib.bus_set_limits(b, ids, mins, maxs, len(ids))
    return mem, b


def _tick(b) -> list[tuple[bytes, int]]:
    """One control tick with no goals: the packets it sends, each with its reply length."""
    out, txn = ffi.new("uint8_t[]", 128), ffi.new("bus_txn *")
    lib.bus_begin_tick(b)
    sent = []
    while n := lib.bus_next(b, ffi.NULL, ffi.NULL, ffi.NULL, 0, out, 128, txn):
        sent.append((bytes(ffi.buffer(out, n)), txn.reply_len))
    return sent


def test_a_servo_that_never_answers_fails_the_check_one_read_per_tick():
    """The check asks again and again, one READ per tick (never two replies awaited in
    one tick), and gives up after BUS_LIMIT_SILENT unanswered READs in a row."""
    _mem, b = _bus_with_limits([5], [300], [700])
    assert lib.bus_limits_state(b) == LimitsState.APPLYING
    for _ in range(lib.BUS_LIMIT_SILENT):
        assert lib.bus_limits_state(b) == LimitsState.APPLYING
        assert _tick(b) == [(read(5, 6, 4), 10)]  # CW/CCW Angle Limit; FF FF id 6 err 4 chk
    lib.bus_begin_tick(b)  # closes the last READ unanswered
    assert lib.bus_limits_state(b) == LimitsState.FAILED
    assert lib.bus_limit_writes(b) == 0
    lib.bus_recheck_limits(b)
    assert lib.bus_limits_state(b) == LimitsState.APPLYING


def test_a_reply_due_to_the_old_check_does_not_count_for_new_limits():
    _mem, b = _bus_with_limits([5], [300], [700])
    out, txn = ffi.new("uint8_t[]", 128), ffi.new("bus_txn *")
    lib.bus_begin_tick(b)
    n = lib.bus_next(b, ffi.NULL, ffi.NULL, ffi.NULL, 0, out, 128, txn)
    assert bytes(ffi.buffer(out, n)) == read(5, 6, 4)  # its reply is now awaited
    lib.bus_set_limits(b, [6], [300], [700], 1)  # new limits while servo 5's reply is due
    reply = status(5, 0, bytes([44, 1, 188, 2]))  # 300, 700: what servo 6 should hold
    assert not lib.bus_rx(b, reply, len(reply))
    lib.bus_rx_done(b)
    assert lib.bus_limits_state(b) == LimitsState.APPLYING  # servo 6 not yet read
    assert _tick(b) == [(read(6, 6, 4), 10)]
