"""``sim://``: the emulated bus as a pyserial URL, through snakebot's own client."""

from __future__ import annotations

import random

import pytest
import serial

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.formats import protocol as P
from snakebot.formats.protocol import CorruptPacket, ErrorFlags, ProtocolError, ServoError
from snakebot.link.transport import DxlClient, PortError, open_port
from snakebot.sim.urlhandler.protocol_sim import forget_named_buses, named_bus


@pytest.fixture(autouse=True)
def _fresh_named_buses():
    forget_named_buses()
    yield
    forget_named_buses()


def client(url: str, **kwargs) -> DxlClient:
    # No USB adapter in between: the latency margin can be 0.
    return DxlClient(url, latency_s=0.0, **kwargs)


def test_snakebot_client_reads_writes_and_sync_writes_over_sim():
    with client("sim://?robot=snake5&return_delay=0") as c:
        bus = c.port.bus
        ids = [s.id for s in bus.servos]
        assert ids == [10, 11, 15, 16]
        assert c.ping(10).error == 0
        assert c.model_number(16) == 12
        c.write_u16(11, 32, 300)  # Moving Speed
        assert c.read_u16(11, 32) == 300
        c.write_u8(15, 25, 1)  # LED
        assert c.read_u8(15, 25) == 1
        goals = {10: 300, 11: 400, 15: 600, 16: 700}
        c.sync_write(30, 2, {i: g.to_bytes(2, "little") for i, g in goals.items()})
        assert {i: c.read_u16(i, 30) for i in ids} == goals
        c.port.timeout = 0.3
        c.port.read(1)  # nothing comes: the bus clock runs on for 0.3 s
        assert {i: c.read_u16(i, 36) for i in ids} == {10: 301, 11: 401, 15: 599, 16: 699}


def test_error_bits_reach_the_client_as_servo_errors():
    with client("sim://?ids=3") as c:
        with pytest.raises(ServoError) as info:
            c.write_u16(3, 36, 0)  # Present Position is read-only
        assert info.value.flags == ErrorFlags.RANGE and info.value.id == 3
        c.write_u16(3, 8, 600)  # CCW Angle Limit
        with pytest.raises(ServoError) as info:
            c.write_u16(3, 30, 700)
        assert info.value.flags == ErrorFlags.ANGLE_LIMIT


def test_echo_on_the_bus_is_recognised_by_the_client():
    with client("sim://?ids=1&echo=1") as c:
        assert c.read_u16(1, 0) == 12
        assert c.echo is True


def test_unknown_options_are_refused_with_the_accepted_form():
    with pytest.raises(serial.SerialException, match="unknown sim:// option 'colour'"):
        serial.serial_for_url("sim://?colour=red")
    with pytest.raises(PortError, match="corrupt"):
        open_port("sim://?corrupt=2")
    with pytest.raises(serial.SerialException, match="robot or a list of servo IDs"):
        serial.serial_for_url("sim://?robot=snake5&ids=1")


def test_a_named_bus_keeps_its_servos_between_openings_and_has_one_master():
    with client("sim://lab?ids=1,2") as c:
        c.send(P.write(2, 3, b"\x07"))  # ID 2 becomes 7 (the status comes from ID 7)
        with pytest.raises(serial.SerialException, match="already open"):
            serial.serial_for_url("sim://lab")
    with client("sim://lab") as c:
        assert c.ping(7).id == 7
    assert [s.id for s in named_bus("lab").servos] == [1, 7]
    with pytest.raises(serial.SerialException, match="other options"):
        serial.serial_for_url("sim://lab?ids=5")


def test_realtime_mode_follows_the_wall_clock():
    with client("sim://?ids=1&realtime=1&return_delay=0") as c:
        assert c.read_u16(1, 36) == 512
        c.write_u16(1, 30, 612)
        port = c.port
        port.timeout = 0.15
        port.read(1)  # 0.15 s of wall time, and of bus time
        assert c.read_u16(1, 36) == 611


def test_one_percent_corruption_never_yields_a_wrong_value():
    """1,000 transactions through snakebot's client with 1 % of the bytes on the wire
    damaged: every value read back is right, or the client reports an error."""
    rng = random.Random(2024)
    with client("sim://?ids=1,2,3&corrupt=0.01&seed=2024&return_delay=0") as c:
        bus = c.port.bus
        goal = {1: 512, 2: 512, 3: 512}
        right = errors = 0
        for k in range(1000):
            sid = rng.choice((1, 2, 3))
            try:
                if k % 2:
                    value = rng.randrange(1024)
                    c.write_u16(sid, 30, value)
                    goal[sid] = value
                else:
                    assert c.read_u16(sid, 30) == goal[sid], f"wrong value at transaction {k}"
                    assert c.read_u8(sid, 3) == sid
                right += 1
            except ProtocolError:
                errors += 1
                # a failed WRITE may still have landed: take the servo's word for it
                goal[sid] = bus.servo(sid).regs.get("Goal Position")
        assert bus.faults.corrupted_bytes > 100  # the faults really happened ...
        assert errors > 0  # ... some were beyond the retries ...
        assert right > 900  # ... and most transactions still succeeded


def test_persistent_corruption_is_reported_not_papered_over():
    with client("sim://?ids=1&corrupt=0.3&seed=5&return_delay=0", retries=1) as c:
        failures = 0
        for _ in range(20):
            try:
                assert c.read_u16(1, 0) == 12
            except (CorruptPacket, ProtocolError):
                failures += 1
        assert failures > 10


def test_a_blocking_read_on_an_idle_bus_returns_after_its_timeout():
    port = serial.serial_for_url("sim://?ids=1", baudrate=1_000_000, timeout=0.05)
    port.write(P.ping(1))
    assert port.read(6) == P.status(1)
    assert port.read(1) == b""  # nothing on its way
    port.close()


def test_every_option_of_the_url_is_understood():
    from snakebot.sim.bus.faults import Brownout, FaultConfig
    from snakebot.sim.options import SimOptions

    options = SimOptions.from_query(
        "robot=snake3&model=AX-12W&baud=57600&return_delay=100&echo=on&ideal=1&voltage=11.1"
        "&seed=9&corrupt=0.001&drop=0.01&delay=2&jitter=0.5&noise=3&noise_len=6"
        "&brownout=1@0.5%2B0.2;2@1%2B0.1&brownout=3@2%2B1"
    )
    assert (options.robot, options.model, options.servo_baud) == ("snake3", "AX-12W", 57600)
    assert (options.return_delay_us, options.echo, options.ideal, options.voltage) == (
        100,
        True,
        True,
        11.1,
    )
    assert options.faults == FaultConfig(
        seed=9,
        corrupt=0.001,
        drop=0.01,
        delay_s=0.002,
        jitter_s=0.0005,
        noise_rate=3,
        noise_len=6,
        brownouts=(Brownout(1, 0.5, 0.2), Brownout(2, 1.0, 0.1), Brownout(3, 2.0, 1.0)),
    )
    bus = options.build_bus()
    assert [s.model for s in bus.servos] == ["AX-12W", "AX-12W"]
    assert {s.regs.get("Baud Rate") for s in bus.servos} == {34}
    assert {s.regs.get("Return Delay Time") for s in bus.servos} == {50}


@pytest.mark.parametrize(
    ("query", "message"),
    [
        ("echo=maybe", "echo=1 or echo=0"),
        ("baud=300", "cannot run at 300"),
        ("ids=1,x", "IDs 0..253"),
        ("brownout=3", "ID@START\\+DURATION"),
        ("model=MX-64", "AX-12A or AX-12W"),
        ("robot=nosuchrobot", "nosuchrobot"),
    ],
)
def test_bad_options_say_what_to_write_instead(query, message):
    with pytest.raises(serial.SerialException, match=message):
        serial.serial_for_url(f"sim://?{query}")
