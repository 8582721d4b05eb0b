"""Virtual AX-12 servos: the control table from the AX-12 descriptions, the instructions,
the error bits, and the motion, voltage and thermal models (in bus time)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st
from sim_support import exchange, make_bus, reply

from snakebot.formats import protocol as P
from snakebot.formats.protocol import ControlTable, ErrorFlags, Instruction
from snakebot.sim.errors import SimOptionError
from snakebot.sim.options import SimOptions
from snakebot.sim.servo import motor
from snakebot.sim.servo.fast import VirtualServo

TABLE = ControlTable.for_model("AX-12A")


def addr(name: str) -> int:
    return TABLE.by_name(name).address


def u16(data: bytes) -> int:
    return int.from_bytes(data, "little")


def read_u16(bus, sid: int, name: str) -> int:
    return u16(reply(bus, P.read(sid, addr(name), 2)).params)


def read_u8(bus, sid: int, name: str) -> int:
    return reply(bus, P.read(sid, addr(name), 1)).params[0]


def write(bus, sid: int, name: str, value: int) -> P.Packet:
    size = TABLE.by_name(name).size
    return reply(bus, P.write(sid, addr(name), value.to_bytes(size, "little")))


# -- the control table ------------------------------------------------------------------


@pytest.mark.parametrize("model", ["AX-12A", "AX-12W"])
def test_fresh_servo_reports_the_factory_values_of_its_model(model):
    bus = make_bus(1, model=model)
    table = ControlTable.for_model(model)
    image = reply(bus, P.read(1, 0, table.size)).params
    assert len(image) == table.size
    for entry in table:
        value = int.from_bytes(image[entry.address : entry.address + entry.size], "little")
        if entry.name == "Goal Position":
            assert value == 512  # a servo starts with its goal at its present position
        elif entry.name == "Present Voltage":
            assert value == 120  # 12 V supply
        elif entry.name == "Present Temperature":
            assert value == round(motor.AMBIENT_C)
        elif entry.name == "Present Position":
            assert value == 512
        elif entry.name == "ID":
            assert value == 1
        elif entry.default is not None:
            assert value == entry.default, entry.name
        elif entry.emulator_default is not None:
            assert value == entry.emulator_default, entry.name
    assert u16(image[0:2]) == table.model_number


def test_the_two_models_differ_where_the_manual_says():
    a, w = make_bus(1, model="AX-12A"), make_bus(1, model="AX-12W")
    assert read_u16(a, 1, "Model Number") == 12
    assert read_u16(w, 1, "Model Number") == 300
    assert read_u8(w, 1, "CW Compliance Margin") == 4
    assert read_u8(w, 1, "CCW Compliance Slope") == 64
    assert read_u8(a, 1, "CW Compliance Slope") == 32


@pytest.mark.parametrize("entry", [e for e in TABLE if e.access == "R"], ids=lambda e: e.name)
def test_writing_a_read_only_register_is_a_range_error_and_changes_nothing(entry):
    bus = make_bus(1)
    before = reply(bus, P.read(1, entry.address, entry.size)).params
    answer = reply(bus, P.write(1, entry.address, bytes(entry.size)))
    assert answer.error == ErrorFlags.RANGE
    assert reply(bus, P.read(1, entry.address, entry.size)).params == before


WRITABLE = [e for e in TABLE if e.access == "RW"]


@pytest.mark.parametrize(
    "entry", [e for e in WRITABLE if e.name != "Status Return Level"], ids=lambda e: e.name
)
def test_each_writable_register_takes_its_range_and_refuses_beyond(entry):
    bus = make_bus(1)
    wait = 0.05  # long enough for a status packet at the slowest baud rate
    limit = (1 << (8 * entry.size)) - 1
    high = limit if entry.max is None else entry.max
    low = 0 if entry.min is None else entry.min
    if entry.name == "Moving Speed":
        high = 1023  # joint mode: bit 10 (direction) only exists in wheel mode
    sid = 1
    for value in (low, high):
        answer = reply(bus, P.write(sid, entry.address, value.to_bytes(entry.size, "little")), wait)
        # (a limit of 0 degrees or volts is legal, and then the servo reports the condition)
        assert not answer.error & ErrorFlags.RANGE, (entry.name, value)
        if entry.name == "ID":
            sid = value
        if entry.name == "Baud Rate":
            bus.baudrate = 2_000_000 / (value + 1)  # follow the servo to its new rate
        assert answer.id == sid
        got = reply(bus, P.read(sid, entry.address, entry.size), wait).params
        assert int.from_bytes(got, "little") == value
        if entry.name == "Lock":
            return  # locked until power is lost: nothing more to write
    beyond = [v for v in (low - 1, high + 1) if 0 <= v <= limit]
    for value in beyond:
        before = reply(bus, P.read(sid, entry.address, entry.size), wait).params
        answer = reply(bus, P.write(sid, entry.address, value.to_bytes(entry.size, "little")), wait)
        assert answer.error & ErrorFlags.RANGE, (entry.name, value)
        assert reply(bus, P.read(sid, entry.address, entry.size), wait).params == before


def test_half_of_a_two_byte_register_and_reserved_addresses_are_range_errors():
    bus = make_bus(1)
    goal = addr("Goal Position")
    assert reply(bus, P.write(1, goal, b"\x00")).error == ErrorFlags.RANGE
    assert reply(bus, P.write(1, goal + 1, b"\x02")).error == ErrorFlags.RANGE
    assert reply(bus, P.write(1, 10, b"\x00")).error == ErrorFlags.RANGE  # reserved
    assert reply(bus, P.write(1, 49, b"\x00\x00")).error == ErrorFlags.RANGE  # off the end
    assert read_u16(bus, 1, "Goal Position") == 512


def test_a_write_spanning_several_registers_is_all_or_nothing():
    bus = make_bus(1)
    # Goal 600 + Moving Speed 100 in one packet: both applied.
    ok = reply(bus, P.write(1, addr("Goal Position"), bytes([88, 2, 100, 0])))
    assert ok.error == 0
    assert read_u16(bus, 1, "Moving Speed") == 100
    # Goal 700 + Moving Speed 5000 (out of range): neither applied.
    bad = reply(
        bus, P.write(1, addr("Goal Position"), (700).to_bytes(2, "little") + bytes([136, 19]))
    )
    assert bad.error == ErrorFlags.RANGE
    assert read_u16(bus, 1, "Goal Position") == 600


def test_reads_past_the_end_of_the_table_are_range_errors():
    bus = make_bus(1)
    answer = reply(bus, P.read(1, TABLE.size - 1, 2))
    assert answer.error == ErrorFlags.RANGE and answer.params == b""
    assert reply(bus, P.read(1, TABLE.size - 1, 1)).error == 0


def test_goal_outside_the_angle_limits_is_refused_with_the_angle_limit_bit():
    bus = make_bus(1)
    assert write(bus, 1, "CW Angle Limit", 300).error == 0
    assert write(bus, 1, "CCW Angle Limit", 700).error == 0
    assert write(bus, 1, "Goal Position", 299).error == ErrorFlags.ANGLE_LIMIT
    assert write(bus, 1, "Goal Position", 701).error == ErrorFlags.ANGLE_LIMIT
    assert read_u16(bus, 1, "Goal Position") == 512
    assert write(bus, 1, "Goal Position", 700).error == 0


# -- instructions -----------------------------------------------------------------------


def test_unknown_instructions_and_bulk_read_get_the_instruction_bit():
    bus = make_bus(1)
    assert reply(bus, P.encode_packet(1, 0x20)).error == ErrorFlags.INSTRUCTION
    # BULK_READ is an MX instruction; an AX-12 addressed directly does not know it ...
    assert reply(bus, P.encode_packet(1, Instruction.BULK_READ, b"\x00\x02\x01\x24")).error == (
        ErrorFlags.INSTRUCTION
    )
    # ... and on the broadcast ID it stays silent, as AX servos do.
    assert exchange(bus, P.bulk_read([(1, 36, 2)])) == []


def test_action_without_reg_write_is_an_instruction_error():
    bus = make_bus(1)
    assert reply(bus, P.action(1)).error == ErrorFlags.INSTRUCTION


def test_reg_write_waits_for_action_and_broadcast_action_moves_every_servo():
    bus = make_bus(1, 2, ideal=True)
    for sid, goal in ((1, 300), (2, 700)):
        assert (
            reply(bus, P.reg_write(sid, addr("Goal Position"), goal.to_bytes(2, "little"))).error
            == 0
        )
        assert read_u8(bus, sid, "Registered") == 1
    bus.run_until(bus.now + 0.5)
    assert [read_u16(bus, s, "Present Position") for s in (1, 2)] == [512, 512]
    assert exchange(bus, P.action(P.BROADCAST_ID)) == []  # broadcast: no status packets
    assert [read_u16(bus, s, "Present Position") for s in (1, 2)] == [300, 700]
    assert [read_u8(bus, s, "Registered") for s in (1, 2)] == [0, 0]


def test_broadcast_write_applies_to_all_and_is_never_answered():
    bus = make_bus(1, 2, 3)
    assert exchange(bus, P.write(P.BROADCAST_ID, addr("LED"), b"\x01")) == []
    assert [read_u8(bus, s, "LED") for s in (1, 2, 3)] == [1, 1, 1]
    assert exchange(bus, P.ping(P.BROADCAST_ID)) == []


def test_sync_write_gives_each_servo_its_own_slice():
    bus = make_bus(1, 2, 3)
    goals = {1: 100, 2: 200, 3: 900}
    packet = P.sync_write(
        addr("Goal Position"), 2, {i: g.to_bytes(2, "little") for i, g in goals.items()}
    )
    assert exchange(bus, packet) == []
    assert {s: read_u16(bus, s, "Goal Position") for s in goals} == goals
    assert {s: read_u8(bus, s, "Torque Enable") for s in goals} == {1: 1, 2: 1, 3: 1}


def test_reset_restores_factory_values_and_answers_from_the_old_id():
    bus = make_bus(7)
    assert write(bus, 7, "Return Delay Time", 0).error == 0
    assert write(bus, 7, "CCW Angle Limit", 800).error == 0
    answer = reply(bus, P.reset(7))
    assert answer.id == 7 and answer.error == 0
    assert exchange(bus, P.ping(7)) == []
    assert reply(bus, P.ping(1)).error == 0
    assert read_u8(bus, 1, "Return Delay Time") == 250
    assert read_u16(bus, 1, "CCW Angle Limit") == 1023


def test_a_new_id_answers_at_once_and_the_old_one_is_gone():
    bus = make_bus(1)
    answer = write(bus, 1, "ID", 42)
    assert answer.id == 42
    assert exchange(bus, P.ping(1)) == []
    assert reply(bus, P.ping(42)).error == 0


def test_a_damaged_instruction_gets_the_checksum_bit_from_the_id_it_names():
    bus = make_bus(1, 2)
    bad = bytearray(P.write(2, addr("LED"), b"\x01"))
    bad[-1] ^= 0xFF
    answer = reply(bus, bytes(bad))
    assert answer.id == 2 and answer.error == ErrorFlags.CHECKSUM
    assert read_u8(bus, 2, "LED") == 0


def test_status_return_level_above_2_is_a_range_error():
    bus = make_bus(1)
    assert reply(bus, P.write(1, addr("Status Return Level"), b"\x03")).error == ErrorFlags.RANGE


@pytest.mark.parametrize(
    ("level", "read_answered", "write_answered"),
    [(0, False, False), (1, True, False), (2, True, True)],
)
def test_status_return_level_decides_what_is_answered(level, read_answered, write_answered):
    bus = make_bus(1)
    exchange(bus, P.write(1, addr("Status Return Level"), bytes([level])))
    assert bool(exchange(bus, P.ping(1)))  # PING is always answered
    assert bool(exchange(bus, P.read(1, 36, 2))) == read_answered
    assert bool(exchange(bus, P.write(1, addr("LED"), b"\x01"))) == write_answered
    assert bus.servo(1).regs.get("LED") == 1  # written either way


def test_lock_allows_only_torque_enable_to_torque_limit_until_power_is_lost():
    bus = make_bus(1)
    assert write(bus, 1, "Lock", 1).error == 0
    assert write(bus, 1, "Return Delay Time", 10).error == ErrorFlags.RANGE
    assert write(bus, 1, "Punch", 64).error == ErrorFlags.RANGE
    assert write(bus, 1, "Lock", 1).error == ErrorFlags.RANGE
    assert write(bus, 1, "Goal Position", 600).error == 0
    assert write(bus, 1, "Torque Limit", 500).error == 0
    servo = bus.servo(1)
    servo.power_off(bus.now)
    servo.power_on(bus.now + 0.1)
    bus.run_until(bus.now + 0.1)
    assert read_u8(bus, 1, "Lock") == 0
    assert write(bus, 1, "Return Delay Time", 10).error == 0


# -- motion -----------------------------------------------------------------------------


def test_the_servo_moves_at_its_no_load_speed_and_stops_within_the_margin():
    bus = make_bus(1)
    assert read_u8(bus, 1, "Torque Enable") == 0
    t0 = bus.now
    write(bus, 1, "Goal Position", 812)  # 300 ticks away
    assert read_u8(bus, 1, "Torque Enable") == 1  # a goal switches the torque on
    speed = motor.SPECS["AX-12A"].no_load_rpm * motor.TICKS_PER_S_PER_RPM  # ticks/s
    bus.run_until(t0 + 0.1)
    pos = read_u16(bus, 1, "Present Position")
    assert abs(pos - (512 + speed * 0.1)) <= 2
    assert read_u8(bus, 1, "Moving") == 1
    present_speed = read_u16(bus, 1, "Present Speed")
    assert present_speed & motor.DIRECTION_BIT == 0  # CCW: toward larger positions
    assert abs(present_speed - 59 / motor.SPEED_UNIT_RPM) <= 2
    bus.run_until(t0 + 0.5)
    assert read_u16(bus, 1, "Present Position") == 812 - 1  # CW margin 1: stops at its edge
    assert read_u8(bus, 1, "Moving") == 0
    assert read_u16(bus, 1, "Present Speed") == 0


def test_moving_speed_and_supply_voltage_set_the_speed():
    slow = make_bus(1)
    write(slow, 1, "Moving Speed", 100)  # 11.1 rpm
    t0 = slow.now
    write(slow, 1, "Goal Position", 100)  # going CW
    slow.run_until(t0 + 0.5)
    expected = 512 - 100 * motor.SPEED_UNIT_RPM * motor.TICKS_PER_S_PER_RPM * 0.5
    assert abs(read_u16(slow, 1, "Present Position") - expected) <= 2
    assert read_u16(slow, 1, "Present Speed") == 100 | motor.DIRECTION_BIT

    low_v = make_bus(1, supply_v=9.0)
    assert read_u8(low_v, 1, "Present Voltage") == 90
    t0 = low_v.now
    write(low_v, 1, "Goal Position", 1000)
    low_v.run_until(t0 + 0.1)
    full = motor.SPECS["AX-12A"].no_load_rpm * motor.TICKS_PER_S_PER_RPM
    assert abs(read_u16(low_v, 1, "Present Position") - (512 + full * 0.75 * 0.1)) <= 2


def test_wheel_mode_turns_endlessly_with_bit_10_as_direction():
    bus = make_bus(1)
    assert write(bus, 1, "Moving Speed", 1500).error == ErrorFlags.RANGE  # joint mode
    write(bus, 1, "CW Angle Limit", 0)
    write(bus, 1, "CCW Angle Limit", 0)
    write(bus, 1, "Torque Enable", 1)
    assert write(bus, 1, "Moving Speed", 1023 | motor.DIRECTION_BIT).error == 0  # full CW
    seen = []
    for _ in range(40):
        bus.run_until(bus.now + 0.05)
        seen.append(bus.positions([1])[0])
    steps = [(b - a) % motor.TICKS_PER_REV for a, b in zip(seen, seen[1:], strict=False)]
    assert all(s > motor.TICKS_PER_REV / 2 for s in steps)  # always decreasing (mod a turn)
    assert max(seen) - min(seen) > 1000  # went all the way round
    assert read_u16(bus, 1, "Present Speed") & motor.DIRECTION_BIT


def test_ideal_servos_are_at_their_goal_at_once():
    bus = make_bus(1, ideal=True)
    write(bus, 1, "Goal Position", 900)
    assert read_u16(bus, 1, "Present Position") == 900


def test_overload_cuts_the_torque_until_torque_limit_is_written():
    bus = make_bus(1)
    servo = bus.servo(1)
    write(bus, 1, "Goal Position", 600)
    servo.set_external_torque(bus.now, -2.0)  # more than the 1.5 N m stall torque
    answer = reply(bus, P.ping(1))
    assert answer.error & ErrorFlags.OVERLOAD
    assert read_u16(bus, 1, "Torque Limit") == 0  # Shutdown has the overload bit by default
    pos = servo.pos
    servo.set_external_torque(bus.now, 0.0)
    bus.run_until(bus.now + 0.5)
    assert servo.pos == pos  # no torque: it stays put
    assert reply(bus, P.ping(1)).error & ErrorFlags.OVERLOAD  # still reported ...
    assert write(bus, 1, "Torque Limit", 1023).error == 0  # ... until Torque Limit is written
    assert reply(bus, P.ping(1)).error == 0
    bus.run_until(bus.now + 0.5)
    assert read_u16(bus, 1, "Present Position") == 599


def test_load_is_reported_with_its_direction():
    bus = make_bus(1)
    write(bus, 1, "Torque Enable", 1)
    bus.servo(1).set_external_torque(bus.now, 0.75)  # half the stall torque, pushing CCW
    bus.run_until(bus.now + 0.05)
    load = read_u16(bus, 1, "Present Load")
    assert load & motor.DIRECTION_BIT  # the servo pushes back CW
    assert abs((load & 1023) - 512) <= 2


def test_heat_builds_under_load_until_the_overheating_alarm():
    bus = make_bus(1)
    servo = bus.servo(1)
    write(bus, 1, "Torque Enable", 1)
    servo.set_external_torque(bus.now, 1.2)  # heavy, but below stall
    temps = [read_u8(bus, 1, "Present Temperature")]
    while not reply(bus, P.ping(1)).error:
        bus.run_until(bus.now + 5)
        temps.append(read_u8(bus, 1, "Present Temperature"))
        assert len(temps) < 100, "never overheated"
    assert temps == sorted(temps) and temps[0] == 25
    # (the alarm trips inside the last 5 s, so the servo has cooled a little since)
    assert temps[-1] >= read_u8(bus, 1, "Temperature Limit") - 2
    assert reply(bus, P.ping(1)).error & ErrorFlags.OVERHEATING
    assert read_u16(bus, 1, "Torque Limit") == 0  # the alarm cut the torque
    bus.run_until(bus.now + 60)
    assert read_u8(bus, 1, "Present Temperature") < temps[-1]  # unloaded, it cools


def test_supply_outside_the_voltage_limits_sets_the_input_voltage_bit():
    bus = make_bus(1, supply_v=5.0)
    answer = reply(bus, P.ping(1))
    assert answer.error == ErrorFlags.INPUT_VOLTAGE
    bus.set_supply(12.0)
    assert reply(bus, P.ping(1)).error == 0


# -- EEPROM in a state file ------------------------------------------------------------


def test_eeprom_survives_in_a_state_file_and_ram_does_not(tmp_path):
    state = tmp_path / "servos.json"
    options = SimOptions.from_query(f"ids=1,2&state={state}")
    bus = options.build_bus()
    write(bus, 2, "ID", 9)
    write(bus, 9, "CW Angle Limit", 100)
    write(bus, 1, "LED", 1)
    again = options.build_bus()
    assert [s.id for s in again.servos] == [1, 9]
    assert read_u16(again, 9, "CW Angle Limit") == 100
    assert read_u8(again, 1, "LED") == 0  # RAM starts from power-on values


def test_a_state_file_for_other_servos_is_refused_with_the_fix(tmp_path):
    state = tmp_path / "servos.json"
    SimOptions.from_query(f"ids=1,2&state={state}").build_bus()
    with pytest.raises(Exception, match="delete the file"):
        SimOptions.from_query(f"ids=1&state={state}").build_bus()


def test_servo_refuses_impossible_construction():
    with pytest.raises(SimOptionError, match="AX-12A or AX-12W"):
        VirtualServo(1, "MX-28")


# -- whatever arrives, the table stays within its documented ranges ----------------------

packets = st.one_of(
    st.builds(
        lambda sid, address, data: P.write(sid, address, data),
        st.sampled_from([1, P.BROADCAST_ID, 2]),
        st.integers(0, 60),
        st.binary(min_size=1, max_size=6),
    ),
    st.builds(
        lambda sid, address, data: P.reg_write(sid, address, data),
        st.sampled_from([1, P.BROADCAST_ID]),
        st.integers(0, 60),
        st.binary(min_size=1, max_size=4),
    ),
    st.builds(lambda sid: P.action(sid), st.sampled_from([1, P.BROADCAST_ID])),
    st.builds(
        lambda sid, code, params: P.encode_packet(sid, code, params),
        st.sampled_from([1, P.BROADCAST_ID]),
        st.integers(0, 255),
        st.binary(max_size=8),
    ),
    st.binary(min_size=1, max_size=20),  # line noise
)


@given(st.lists(packets, max_size=25))
def test_no_sequence_of_packets_puts_a_register_out_of_its_range(stream):
    bus = make_bus(1)
    servo = bus.servo(1)
    for packet in stream:
        bus.master_write(packet)
        bus.run_until(bus.now + 0.002)
        bus.master_read(1 << 16)
    wheel = servo.wheel_mode
    for entry in TABLE:
        if not entry.writable or entry.name == "ID":
            continue
        value = servo.regs.get(entry.name)
        low = 0 if entry.min is None else entry.min
        high = (1 << (8 * entry.size)) - 1 if entry.max is None else entry.max
        if entry.name == "Moving Speed" and not wheel:
            high = 2047  # written in wheel mode, then the limits changed: the servo keeps it
        assert low <= value <= high, entry.name
    if not wheel:
        assert 0 <= servo.pos <= 1023
