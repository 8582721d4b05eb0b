"""The robot's Torque Limit in the bus master (issue #17): the C core (through cffi) drives
emulated AX-12s (snakebot.sim's VirtualServo, answering the very packets it sends), and
holds each covered servo's Torque Limit to the robot's, after its angle limits; the audit
finds a servo whose power cycle reset it to Max Torque and writes it again. The LIMITS
blob carries it as an optional last field, range-checked against the servo description."""

from __future__ import annotations

import pytest
from ctl_support import CTL, CTL_ID, Device

from snakebot.core import ffi, lib
from snakebot.facts import devices
from snakebot.formats.protocol import Instruction, PacketParser, write
from snakebot.formats.upload_writes import chunk_writes, commit_write
from snakebot.link.controller import LimitsState, UploadResult
from snakebot.link.controller.limits import encode_limits
from snakebot.sim.servo.fast import VirtualServo

AX12 = devices.ax12()
CW, TORQUE, MAX_TORQUE = (
    AX12.register(n) for n in ("CW Angle Limit", "Torque Limit", "Max Torque")
)
IDS = [1, 2, 3]
LIMITS = [(300, 700), (250, 750), (200, 800)]
ROBOT_TORQUE = TORQUE.from_units(60.0)  # 60 % of stall torque
TICK_S = 0.01


class Rig:
    """A bus master over emulated servos: each tick's packets go to every servo, and a
    READ's status packet comes back to the master."""

    def __init__(self) -> None:
        self.mem = ffi.new("uint8_t[]", lib.bus_master_size())
        self.b = ffi.cast("bus_master *", self.mem)
        lib.bus_init(self.b)
        self.servos = {sid: VirtualServo(sid, ideal=True) for sid in IDS}
        self.t = 0.0
        self.sent: list[tuple[int, int, int, bytes]] = []  # (id, instruction, address, data)

    def set_limits(self, torque: int | None) -> None:
        lib.bus_set_limits(self.b, IDS, [lo for lo, _ in LIMITS], [hi for _, hi in LIMITS], 3)
        if torque is not None:
            lib.bus_set_torque_limit(self.b, torque)

    def tick(self) -> None:
        out, txn = ffi.new("uint8_t[]", 128), ffi.new("bus_txn *")
        self.t += TICK_S
        lib.bus_begin_tick(self.b)
        while n := lib.bus_next(self.b, ffi.NULL, ffi.NULL, ffi.NULL, 0, out, 128, txn):
            (packet,) = PacketParser().feed(bytes(ffi.buffer(out, n)))
            self.sent.append((packet.id, packet.code, packet.params[0], bytes(packet.params[1:])))
            for servo in self.servos.values():
                reply = servo.receive(packet, self.t)
                if reply is not None and txn.reply_len:
                    lib.bus_rx(self.b, reply[0], len(reply[0]))

    def state(self) -> int:
        return lib.bus_limits_state(self.b)

    def settle(self, ticks: int = 400) -> int:
        for _ in range(ticks):
            self.tick()
            if self.state() != LimitsState.APPLYING:
                break
        return self.state()

    def writes_to(self, register) -> dict[int, int]:
        """WRITE packets each servo got at the register's address."""
        return {
            sid: sum(
                1
                for i, code, addr, _ in self.sent
                if i == sid and code == Instruction.WRITE and addr == register.address
            )
            for sid in IDS
        }

    def held(self, register) -> list[int]:
        return [s.regs.get(register.name) for s in self.servos.values()]

    def preset(self, sid: int, register, value: int) -> None:
        self.servos[sid].set_register(register.name, value)


def _fresh() -> Rig:
    """A rig whose servos hold the robot's angle limits already."""
    r = Rig()
    for sid, (lo, hi) in zip(IDS, LIMITS, strict=True):
        r.preset(sid, CW, lo)
        r.servos[sid].set_register("CCW Angle Limit", hi)
    return r


@pytest.fixture
def rig() -> Rig:
    return _fresh()


def test_a_servo_whose_torque_limit_differs_is_written_once_and_verified(rig):
    rig.preset(1, TORQUE, ROBOT_TORQUE)  # servo 1 holds it already; 2 and 3 their default
    rig.preset(3, CW, 0)  # servo 3's angle limits differ too
    rig.set_limits(ROBOT_TORQUE)
    assert lib.bus_torque_limit(rig.b) == ROBOT_TORQUE

    assert rig.settle() == LimitsState.VERIFIED
    assert rig.held(TORQUE) == [ROBOT_TORQUE] * 3
    assert rig.writes_to(TORQUE) == {1: 0, 2: 1, 3: 1}
    assert rig.writes_to(CW) == {1: 0, 2: 0, 3: 1}
    assert lib.bus_limit_writes(rig.b) == 1  # the EEPROM count: Torque Limit is RAM
    # each servo's Torque Limit is asked only once its angle limits are verified
    for sid in IDS:
        steps = [(code, addr) for i, code, addr, _ in rig.sent if i == sid]
        first_torque = steps.index((Instruction.READ, TORQUE.address))
        assert (Instruction.WRITE, CW.address) not in steps[first_torque:]


def ticks_to_settle(rig: Rig, torque: int | None) -> int:
    """Ticks until the check is over; VERIFIED is never said before every servo holds
    the robot's Torque Limit."""
    rig.set_limits(torque)
    for n in range(1, 400):
        rig.tick()
        if rig.state() == LimitsState.VERIFIED:
            if torque is not None:
                assert rig.held(TORQUE) == [torque] * 3
            return n
    raise AssertionError("the check never ended")


def test_limits_state_is_applying_until_the_torque_limits_hold(rig):
    angles_only = ticks_to_settle(_fresh(), None)
    assert ticks_to_settle(rig, ROBOT_TORQUE) > angles_only
    assert rig.held(TORQUE) == [ROBOT_TORQUE] * 3


def test_a_servo_reset_to_max_torque_is_found_by_the_audit_and_rewritten(rig):
    rig.set_limits(ROBOT_TORQUE)
    assert rig.settle() == LimitsState.VERIFIED
    before = rig.writes_to(TORQUE)
    rig.servos[2].power_off(rig.t)  # a power cycle: RAM back to power-on values
    rig.servos[2].power_on(rig.t)
    assert rig.held(TORQUE)[1] == MAX_TORQUE.default
    seen_applying = False
    # the audit reads one register of one servo every BUS_LIMIT_AUDIT_TICKS ticks
    for _ in range(2 * len(IDS) * lib.BUS_LIMIT_AUDIT_TICKS + 20):
        rig.tick()
        seen_applying |= rig.state() == LimitsState.APPLYING
        if rig.held(TORQUE)[1] == ROBOT_TORQUE and rig.state() == LimitsState.VERIFIED:
            break
    assert seen_applying
    assert rig.held(TORQUE) == [ROBOT_TORQUE] * 3
    after = rig.writes_to(TORQUE)
    assert after == {**before, 2: before[2] + 1}
    assert lib.bus_limit_writes(rig.b) == 0  # no EEPROM write: the angle limits held


def test_without_a_robot_torque_limit_the_servos_keep_their_own(rig):
    rig.preset(2, TORQUE, 100)
    rig.set_limits(None)
    assert lib.bus_torque_limit(rig.b) == lib.BUS_TORQUE_LIMIT_NONE
    assert rig.settle() == LimitsState.VERIFIED
    for _ in range(4 * len(IDS) * lib.BUS_LIMIT_AUDIT_TICKS):  # audits included
        rig.tick()
    assert rig.held(TORQUE) == [TORQUE.default, 100, TORQUE.default]
    assert all(addr != TORQUE.address for _, _, addr, _ in rig.sent)
    # new angle limits forget a torque limit set before
    lib.bus_set_torque_limit(rig.b, ROBOT_TORQUE)
    rig.set_limits(None)
    assert lib.bus_torque_limit(rig.b) == lib.BUS_TORQUE_LIMIT_NONE


def commit(dev: Device, blob: bytes) -> int:
    for address, data in chunk_writes(blob, controller=CTL):
        assert dev.one(write(CTL_ID, address, data)).error == 0
    assert dev.one(write(CTL_ID, *commit_write(blob, CTL, what="LIMITS"))).error == 0
    return dev.get("Upload Result")


def kept(dev: Device) -> bytes:
    out = ffi.new("uint8_t[]", 128)
    return bytes(ffi.buffer(out, lib.ctl_robot_limits(dev.d, out, 128)))


ROBOT = dict(zip(IDS, LIMITS, strict=True))


@pytest.mark.parametrize("torque", [None, ROBOT_TORQUE, TORQUE.value_range()[1]])
def test_the_limits_blob_with_and_without_the_torque_field(torque):
    dev = Device()
    blob = encode_limits(ROBOT, torque)
    assert len(blob) == 1 + 5 * len(ROBOT) + (0 if torque is None else TORQUE.size)
    assert commit(dev, blob) == UploadResult.OK
    assert dev.get("Limits Count") == len(ROBOT)
    # what the CM-530 stores is the blob as set (the torque field too, if given), and it
    # loads back the same
    assert kept(dev) == blob
    fresh = Device()
    assert lib.ctl_load_limits(fresh.d, blob, len(blob))
    assert kept(fresh) == blob


def test_a_record_stored_before_the_torque_field_still_loads():
    blob = encode_limits(ROBOT)  # the flash record older firmware wrote
    dev = Device()
    assert lib.ctl_load_limits(dev.d, blob, len(blob))
    assert dev.get("Limits Count") == len(ROBOT)
    assert kept(dev) == blob  # no torque field: the servos' own Torque Limit is left alone


@pytest.mark.parametrize("extra", [b"\x01", b"\x01\x02\x03", b"\xff\xff"])
def test_a_torque_field_out_of_range_or_of_the_wrong_length_is_refused(extra):
    dev = Device()
    assert commit(dev, encode_limits(ROBOT, ROBOT_TORQUE)) == UploadResult.OK
    before = kept(dev)
    assert commit(dev, encode_limits(ROBOT) + extra) == UploadResult.BAD_ROBOT_LIMITS
    assert kept(dev) == before  # nothing half-applied


def test_the_torque_range_the_firmware_checks_is_the_servo_descriptions():
    _, high = TORQUE.value_range()
    assert not lib.ctl_load_limits(Device().d, *_blob(high + 1))
    assert lib.ctl_load_limits(Device().d, *_blob(high))


def _blob(torque: int) -> tuple[bytes, int]:
    blob = encode_limits(ROBOT) + torque.to_bytes(TORQUE.size, "little")
    return blob, len(blob)
