"""PortIO: the client's write and timed read, direct on a POSIX serial port (a real
pty here) and through pyserial on any other port."""

from __future__ import annotations

import os
import time

import pytest
import serial

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.formats import protocol
from snakebot.link.transport.portio import POLLED_TAIL_S, PortIO


@pytest.fixture
def pty_port():
    master, slave = os.openpty()
    port = serial.Serial(os.ttyname(slave), 1_000_000, timeout=0)
    os.close(slave)
    yield master, port
    port.close()
    try:
        os.close(master)
    except OSError:
        pass


def test_on_a_pty_bytes_go_both_ways_and_a_read_waits_at_most_its_timeout(pty_port):
    master, port = pty_port
    io = PortIO(port)
    io.write(b"\xff\xff\x01\x02\x01\xfb")
    assert os.read(master, 64) == b"\xff\xff\x01\x02\x01\xfb"
    os.write(master, b"abcdef")
    assert io.read(4, 1.0) == b"abcd"  # no more than asked for
    assert io.read(16, 1.0) == b"ef"  # what there is, at once
    start = time.monotonic()
    assert io.read(8, 0.05) == b""
    assert 0.04 < time.monotonic() - start < 1.0


def test_a_hung_up_pty_is_a_serial_error_not_an_empty_read(pty_port):
    master, port = pty_port
    io = PortIO(port)
    os.close(master)
    with pytest.raises(serial.SerialException):
        io.read(8, 0.5)


def test_other_ports_go_through_pyserial_with_the_timeout_applied():
    port = serial.serial_for_url("sim://?ids=1&return_delay=0", baudrate=1_000_000)
    try:
        io = PortIO(port)
        io.write(protocol.ping(1))
        reply = io.read(6, 0.01)
        assert port.timeout == pytest.approx(0.01)
        assert protocol.PacketParser().feed(reply)[0].id == 1
    finally:
        port.close()


def test_a_read_within_the_polled_tail_waits_its_whole_timeout_and_sees_what_came(pty_port):
    master, port = pty_port
    io = PortIO(port)
    short = POLLED_TAIL_S / 2  # no sleep at all: polled from the start
    for timeout in (short, POLLED_TAIL_S * 20):
        start = time.monotonic()
        assert io.read(8, timeout) == b""
        assert time.monotonic() - start >= timeout  # never gives up early
        os.write(master, b"xy")
        assert io.read(8, timeout) == b"xy"


def test_flush_input_discards_what_has_arrived_and_nothing_sent_after(pty_port):
    master, port = pty_port
    io = PortIO(port)
    os.write(master, b"stale")
    deadline = time.monotonic() + 2.0
    while port.in_waiting < 5 and time.monotonic() < deadline:  # the pty hands them over
        time.sleep(0.001)
    assert port.in_waiting == 5
    io.flush_input()
    assert port.in_waiting == 0
    os.write(master, b"new")
    assert io.read(16, 1.0) == b"new"


def test_flush_input_on_other_ports_goes_through_pyserial():
    port = serial.serial_for_url("sim://?ids=1&return_delay=0", baudrate=1_000_000)
    try:
        io = PortIO(port)
        io.write(protocol.ping(1))
        port.bus.run_until(port.bus.now + 0.01)  # the whole reply has arrived
        assert port.in_waiting == 6
        io.flush_input()
        assert port.in_waiting == 0
        assert io.read(16, 0.001) == b""
    finally:
        port.close()


@pytest.mark.parametrize("late_s", [0.0, 0.05])
def test_a_client_the_host_runs_late_still_gets_its_reply_from_an_emulated_bus(monkeypatch, late_s):
    """On ``sim://`` a reply is due in the bus's time: a client that the host runs late
    between the pieces of a reply (a busy machine: the fresh-clone flake "no reply to
    WRITE ... within 4.6 ms (3 attempts)") still gets it, on a bus whose clock is its own,
    and the wait a silent servo costs is counted on that clock too."""
    from snakebot.formats.protocol.errors import DxlTimeout
    from snakebot.link.transport import DxlClient
    from snakebot.sim.urlhandler.protocol_sim import Serial as SimSerial

    read = SimSerial.read

    def descheduled_then_one_byte(self, size=1):
        time.sleep(late_s)
        return read(self, min(size, 1))

    monkeypatch.setattr(SimSerial, "read", descheduled_then_one_byte)
    client = DxlClient("sim://?ids=1", retries=0)
    try:
        assert client.timing.reply_timeout_s(8, 2) < late_s or late_s == 0
        assert client.read_u16(1, 36) >= 0  # a READ: its first round, then the attempt
        client.write_u8(1, 25, 1)  # a WRITE's attempt
        assert PortIO(client._port).clock == client._port.port_clock
        with pytest.raises(DxlTimeout):
            client.ping(2)
    finally:
        client.close()


def test_ports_without_a_clock_of_their_own_count_on_the_wall_clock(pty_port):
    assert PortIO(pty_port[1]).clock is time.monotonic
    with serial.serial_for_url("sim://?ids=1&realtime=1") as port:
        before = time.monotonic()
        assert before <= PortIO(port).clock() <= time.monotonic()


@pytest.mark.parametrize("servo_id", [3, 9])  # one that answers, one that is not there
def test_sim_exchange_in_one_call_is_the_three_calls(servo_id):
    # sim:// does a transaction's first round itself (one lock, one bus call each): the
    # same bytes back, at the same bus time, as its flush, write and timed read one by one
    frame = protocol.read(servo_id, 36, 2)
    results = []
    for one_call in (True, False):
        port = serial.serial_for_url("sim://?ids=3&return_delay=100", 1_000_000, timeout=0)
        io = PortIO(port)
        assert io._exchange is not None  # sim:// has its own
        if not one_call:
            io._exchange = None
        port.write(protocol.ping(3))  # something left unread, for the flush to drop
        port.bus.run_until(0.01)
        got = io.exchange(frame, 8, 0.002)
        results.append((got, port.bus.now, port.timeout))
        port.close()
    assert results[0] == results[1]
    assert len(results[0][0]) == (8 if servo_id == 3 else 0)
