"""The emulated wire: timing at the baud rate, servos on the wrong baud, collisions,
echo, the 100 ms gap rule, seeded faults, brownouts, and a world stepping on the clock."""

from __future__ import annotations

import math

import pytest
from sim_support import exchange, make_bus, reply

from snakebot.formats import protocol as P
from snakebot.formats.protocol import Packet, PacketParser
from snakebot.sim.bus.bus import frame_ends
from snakebot.sim.bus.faults import Brownout, FaultConfig
from snakebot.sim.bus.uart import resample
from snakebot.sim.options import SimOptions


def arrival_times(bus, packet: bytes, horizon: float = 0.05) -> list[float]:
    """Send ``packet`` now; return when each byte of the answer reaches the master."""
    bus.master_flush_input()
    bus.master_write(packet)
    end = bus.now + horizon
    times = []
    while bus.run_until_master_data(end):
        times += [bus.now] * len(bus.master_read(1))
    return times


@pytest.mark.parametrize(("baud_reg", "baud"), [(1, 1_000_000), (34, 2_000_000 / 35)])
@pytest.mark.parametrize("delay_reg", [0, 250])
def test_a_read_takes_its_bytes_at_10_bits_each_plus_the_return_delay(baud_reg, baud, delay_reg):
    bus = make_bus(1, baudrate=baud)
    servo = bus.servo(1)
    servo.set_register("Baud Rate", baud_reg)
    servo.set_register("Return Delay Time", delay_reg)
    t0 = bus.now
    times = arrival_times(bus, P.read(1, 36, 2))
    byte = 10 / baud
    first = t0 + 8 * byte + delay_reg * 2e-6 + byte  # instruction out, delay, one byte in
    assert len(times) == 8
    assert times == pytest.approx([first + i * byte for i in range(8)], abs=1e-9)


def test_a_servo_on_another_baud_rate_hears_garbage_and_stays_silent():
    bus = make_bus(1, 2)
    bus.servo(2).set_register("Baud Rate", 34)  # 57 142 bit/s
    assert reply(bus, P.ping(1)).id == 1
    assert exchange(bus, P.ping(2), wait=0.1) == []
    assert exchange(bus, P.write(2, 25, b"\x01"), wait=0.1) == []
    assert bus.servo(2).regs.get("LED") == 0
    bus.baudrate = 57_600  # within the UART tolerance of 57 142
    assert reply(bus, P.ping(2), wait=0.1).id == 2
    assert exchange(bus, P.ping(1), wait=0.1) == []  # now servo 1 is the one left out


def test_two_servos_with_one_id_collide_into_garbage():
    bus = make_bus(3, 3)
    events = exchange(bus, P.read(3, 36, 2))
    assert not any(isinstance(e, Packet) and e.id == 3 and len(e.params) == 2 for e in events)
    assert bus.stats.collisions >= 1


def test_echo_lets_the_master_hear_its_instruction_first():
    bus = make_bus(1, echo=True)
    packet = P.read(1, 36, 2)
    events = exchange(bus, packet)
    assert [e.encode() for e in events] == [packet, P.status(1, 0, (512).to_bytes(2, "little"))]


@pytest.mark.parametrize(("gap", "answered"), [(0.05, True), (0.15, False)])
def test_a_pause_over_100_ms_inside_a_packet_drops_it(gap, answered):
    bus = make_bus(1)
    packet = P.ping(1)
    bus.master_write(packet[:3])
    bus.run_until(bus.now + gap)
    bus.master_write(packet[3:])
    bus.run_until(bus.now + 0.01)
    assert bool(PacketParser().feed(bus.master_read(100))) == answered


def test_a_packet_hidden_after_garbage_is_still_answered_when_its_last_byte_arrives():
    bus = make_bus(1)
    packet = P.ping(1)
    stream = b"\x00\xff\x13" + packet
    assert frame_ends(stream) == [len(stream)]
    times = arrival_times(bus, stream)
    byte = 10e-6
    assert times[0] == pytest.approx(len(stream) * byte + 500e-6 + byte)


def session(faults: FaultConfig, n: int = 200) -> bytes:
    """What the master hears during a fixed script of exchanges."""
    bus = make_bus(1, 2, 3, faults=faults)
    heard = bytearray()
    for k in range(n):
        sid = 1 + k % 3
        bus.master_write(P.read(sid, 36, 2) if k % 2 else P.write(sid, 30, bytes([k % 256, 1])))
        bus.run_until(bus.now + 0.005)
        heard += bus.master_read(1 << 16)
    return bytes(heard)


def test_faults_are_reproducible_from_the_seed():
    faulty = FaultConfig(seed=7, corrupt=0.02, drop=0.05, jitter_s=0.0005, noise_rate=20)
    assert session(faulty) == session(faulty)
    assert session(faulty) != session(
        FaultConfig(seed=8, corrupt=0.02, drop=0.05, jitter_s=0.0005, noise_rate=20)
    )
    assert session(faulty) != session(FaultConfig())


def test_corruption_damages_bytes_at_about_the_given_rate():
    bus = make_bus(1, faults=FaultConfig(seed=1, corrupt=0.01))
    for _ in range(2000):
        exchange(bus, P.read(1, 36, 2), wait=0.002)
    on_wire = bus.stats.master_bytes_out + bus.stats.replies * 8
    rate = bus.faults.corrupted_bytes / on_wire
    assert 0.006 < rate < 0.014


def test_dropped_and_delayed_replies():
    assert exchange(make_bus(1, faults=FaultConfig(drop=1.0)), P.ping(1)) == []
    bus = make_bus(1, faults=FaultConfig(delay_s=0.003))
    t0 = bus.now
    times = arrival_times(bus, P.ping(1))
    assert times[0] == pytest.approx(t0 + 6e-5 + 500e-6 + 0.003 + 1e-5)


def test_noise_bursts_reach_the_master_and_do_not_break_a_later_exchange():
    bus = make_bus(1, faults=FaultConfig(seed=3, noise_rate=50, noise_len=8))
    bus.run_until(1.0)
    heard = bus.master_read(1 << 16)
    assert 20 <= bus.faults.noise_bursts <= 100 and heard
    bus.run_until(bus.now + 0.001)  # the bus is quiet between bursts more often than not
    answers = [exchange(bus, P.ping(1), wait=0.002) for _ in range(20)]
    assert sum(any(isinstance(e, Packet) and e.id == 1 for e in a) for a in answers) >= 15


def test_a_brownout_silences_the_servo_and_resets_its_ram_not_its_eeprom():
    bus = make_bus(1, 2, faults=FaultConfig(brownouts=(Brownout(2, 0.5, 0.2),)))
    assert reply(bus, P.write(2, 5, b"\x00")).error == 0  # Return Delay Time (EEPROM)
    assert reply(bus, P.write(2, 30, (800).to_bytes(2, "little"))).error == 0
    bus.run_until(0.55)
    assert exchange(bus, P.ping(2)) == []
    assert reply(bus, P.ping(1)).id == 1
    bus.run_until(0.75)
    assert reply(bus, P.read(2, 24, 1)).params == b"\x00"  # torque off again
    goal = int.from_bytes(reply(bus, P.read(2, 30, 2)).params, "little")
    present = int.from_bytes(reply(bus, P.read(2, 36, 2)).params, "little")
    assert goal == present != 800  # the goal restarts at the present position
    assert reply(bus, P.read(2, 5, 1)).params == b"\x00"  # EEPROM kept


def test_a_world_steps_on_the_bus_clock_and_sees_the_servos_move():
    bus = SimOptions.from_query("robot=snake5&return_delay=0").build_bus()
    ids = [s.id for s in bus.servos]
    seen: list[tuple[float, list[float]]] = []
    bus.every(0.01, lambda t: seen.append((t, bus.positions(ids))))
    goals = {i: (600).to_bytes(2, "little") for i in ids}
    bus.master_write(P.sync_write(30, 2, goals))
    bus.run_until(0.2)
    assert [round(t, 9) for t, _ in seen] == [round(0.01 * k, 9) for k in range(21)]
    first, last = seen[0][1], seen[-1][1]
    assert first == [512.0] * 4 and last == [599.0] * 4
    travel = [p[0] for _, p in seen]
    assert travel == sorted(travel)


def test_resampling_matches_a_hand_worked_frame():
    # 0x00 at 500 kbit/s lasts 18 us low; a 1 Mbit/s receiver samples the start bit at
    # 0.5 us, eight zero data bits, and a low stop bit at 9.5 us (a framing error, but
    # the byte is delivered). The line then rises and never falls again.
    assert resample(b"\x00", 500_000, 1_000_000) == [(pytest.approx(9.5e-6), 0)]
    data = bytes(range(0, 256, 17))
    assert [b for _, b in resample(data, 1_000_000, 1_000_000)] == list(data)
    assert [b for _, b in resample(data, 1_000_000, 57_600)] != list(data)


def test_sync_write_gives_each_named_servo_the_first_block_that_names_it():
    bus = make_bus(1, 2, 2, 3)  # two servos share ID 2; ID 3 is not named
    packet = bytearray(P.sync_write(30, 2, {1: (400).to_bytes(2, "little")}))
    # a second block for servo 1 (ignored, as a servo takes the first) and one for ID 2
    body = packet[5:-1] + bytes((1, 0x58, 0x02, 2, 0x90, 0x01))
    framed = P.encode_packet(P.BROADCAST_ID, P.Instruction.SYNC_WRITE, bytes(body))
    exchange(bus, framed)
    goals = [s.regs.get("Goal Position") for s in bus.servos]
    assert goals == [400, 400, 400, bus.servo(3).present_position]
    assert [s.regs.get("Torque Enable") for s in bus.servos] == [1, 1, 1, 0]


def test_a_packet_for_one_id_is_handled_by_that_servo_alone(monkeypatch):
    bus = make_bus(*range(1, 19))
    heard = []
    for s in bus.servos:
        monkeypatch.setattr(s, "handle", lambda *a, s=s, f=s.handle: (heard.append(s.id), f(*a))[1])
    # (a WRITE: a READ goes to the C servo whole, past the Python method spied on here)
    assert reply(bus, P.write(7, 25, b"\x01")).id == 7
    assert heard == [7]  # the other 17 are not asked, and nobody parses the reply again
    assert bus.servo(7).regs.get("LED") == 1
    heard.clear()
    exchange(bus, P.write(P.BROADCAST_ID, 25, b"\x01"))
    assert heard == list(range(1, 19))


def test_a_packet_sent_before_an_id_change_lands_reaches_the_servo_by_its_new_id():
    bus = make_bus(1, 2)
    # both go out back to back: the READ is on the wire before the WRITE has landed
    bus.master_write(P.write(1, 3, b"\x07"))  # servo 1 becomes servo 7
    bus.master_write(P.read(7, 36, 2))
    bus.run_until(bus.now + 0.01)
    events = PacketParser().feed(bus.master_read(1 << 16))
    assert [(e.id, len(e.params)) for e in events if isinstance(e, Packet)] == [(7, 0), (7, 2)]


def test_a_tapped_bus_hands_every_packet_to_the_python_handlers(monkeypatch):
    # whole goals SYNC_WRITEs and READs go to the C servos past the Python handlers; a
    # test or tool that wraps those handlers calls tap() and then hears every one
    for tapped in (False, True):
        bus = make_bus(1, 2)
        if tapped:
            bus.tap()
        heard = []
        for s in bus.servos:
            f = s.sync_write_block
            monkeypatch.setattr(
                s,
                "sync_write_block",
                lambda *a, s=s, f=f, heard=heard: (heard.append(s.id), f(*a))[1],
            )
        goals = {1: (400).to_bytes(2, "little"), 2: (600).to_bytes(2, "little")}
        exchange(bus, P.sync_write(30, 2, goals))
        assert [s.regs.get("Goal Position") for s in bus.servos] == [400, 600]
        assert heard == ([1, 2] if tapped else [])


def test_replies_on_their_way_back_to_back_are_coming_as_they_will_be_read():
    # Two PINGs in one write: servo 1's answer ends 10 us before servo 2's begins, two
    # streams on their way to the master at once (no collision). The emulated CM-530
    # hands USART1 what master_coming says is coming; with nothing said while several
    # streams came, it heard nothing more from then on (the fault campaigns' damaged
    # packets made servos answer so).
    bus = make_bus(1, 2)
    bus.servo(2).set_register("Return Delay Time", 255)  # 510 us to servo 1's 500
    bus.master_write(P.ping(1) + P.ping(2))
    bus.run_until(bus.now + 12 * 10e-6 + 1e-9)  # both PINGs heard, both answers on the way
    data, times, after = bus.master_coming(math.inf, 64)
    assert [(p.id, p.params) for p in PacketParser().feed(data)] == [(1, b""), (2, b"")]
    assert times == sorted(times) and after is None
    first, _, next_t = bus.master_coming(times[3], 64)  # the bytes complete before then
    assert first == data[:3] and next_t == times[3]
    assert bus.master_coming(math.inf, 5)[:2] == (data[:5], times[:5])
    bus.run_until(times[-1])
    assert bus.master_read(64) == data  # what master_read takes, in that order
