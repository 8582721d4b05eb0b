"""The emulated bus on a real pseudo-terminal: ROBOTIS's dynamixel-sdk (a third-party
client that knows nothing of the emulator) and snakebot's own client, and the
`snakebot sim bus` command that serves it."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import dynamixel_sdk as sdk
import pytest
from realtime import ordinary_priority

from snakebot.formats import protocol as P
from snakebot.link.transport import DxlClient, open_port
from snakebot.sim.options import SimOptions
from snakebot.sim.transports import PtyServer

# dynamixel-sdk waits its own fixed time for a reply: run with nothing beside it.
pytestmark = pytest.mark.serial

IDS = (10, 11, 15, 16)  # snake5's servos


@pytest.fixture(scope="module")
def served():
    bus = SimOptions.from_query("robot=snake5").build_bus()
    with PtyServer(bus) as server:
        yield server


@pytest.fixture
def sdk_port(served):
    port = sdk.PortHandler(served.device)
    assert port.openPort()
    assert port.setBaudRate(1_000_000)
    with ordinary_priority():  # the SDK polls; the server's thread keeps its class
        yield port
    port.closePort()


PH = sdk.PacketHandler(1.0)


def ok(result: int, error: int = 0) -> None:
    assert result == sdk.COMM_SUCCESS, PH.getTxRxResult(result)
    assert error == 0, PH.getRxPacketError(error)


def test_dynamixel_sdk_pings_every_servo_and_reads_the_model(sdk_port):
    for sid in IDS:
        model, result, error = PH.ping(sdk_port, sid)
        ok(result, error)
        assert model == 12
    _, result, _ = PH.ping(sdk_port, 99)
    assert result == sdk.COMM_RX_TIMEOUT


def test_dynamixel_sdk_one_and_two_byte_reads_and_writes(sdk_port):
    value, result, error = PH.read1ByteTxRx(sdk_port, 11, 3)  # ID
    ok(result, error)
    assert value == 11
    value, result, error = PH.read2ByteTxRx(sdk_port, 11, 36)  # Present Position
    ok(result, error)
    assert value == 512
    ok(*PH.write1ByteTxRx(sdk_port, 11, 25, 1))  # LED
    value, result, error = PH.read1ByteTxRx(sdk_port, 11, 25)
    ok(result, error)
    assert value == 1
    ok(*PH.write2ByteTxRx(sdk_port, 11, 32, 345))  # Moving Speed
    value, result, error = PH.read2ByteTxRx(sdk_port, 11, 32)
    ok(result, error)
    assert value == 345


def test_dynamixel_sdk_sync_write_reaches_several_servos(sdk_port):
    group = sdk.GroupSyncWrite(sdk_port, PH, 30, 2)
    goals = {10: 300, 11: 400, 15: 600, 16: 700}
    for sid, goal in goals.items():
        assert group.addParam(sid, [sdk.DXL_LOBYTE(goal), sdk.DXL_HIBYTE(goal)])
    assert group.txPacket() == sdk.COMM_SUCCESS
    for sid, goal in goals.items():
        value, result, error = PH.read2ByteTxRx(sdk_port, sid, 30)
        ok(result, error)
        assert value == goal
        torque, result, error = PH.read1ByteTxRx(sdk_port, sid, 24)
        ok(result, error)
        assert torque == 1


def test_dynamixel_sdk_sees_the_documented_error_bits(sdk_port):
    result, error = PH.write2ByteTxRx(sdk_port, 15, 36, 0)  # read-only
    assert result == sdk.COMM_SUCCESS and error == sdk.protocol1_packet_handler.ERRBIT_RANGE
    result, error = PH.write1ByteTxRx(sdk_port, 15, 16, 3)  # Status Return Level 0..2
    assert result == sdk.COMM_SUCCESS and error == sdk.protocol1_packet_handler.ERRBIT_RANGE
    ok(*PH.write2ByteTxRx(sdk_port, 15, 6, 200))  # CW Angle Limit
    result, error = PH.write2ByteTxRx(sdk_port, 15, 30, 100)  # goal below it
    assert result == sdk.COMM_SUCCESS and error == sdk.protocol1_packet_handler.ERRBIT_ANGLE
    ok(*PH.write2ByteTxRx(sdk_port, 15, 6, 0))
    # an instruction the AX-12 does not know
    _, result, error = PH.txRxPacket(sdk_port, [0, 0, 15, 2, 0x20, 0])
    assert result == sdk.COMM_SUCCESS
    assert error == sdk.protocol1_packet_handler.ERRBIT_INSTRUCTION
    # a damaged checksum, sent raw
    bad = bytearray(P.write(15, 25, b"\x01"))
    bad[-1] ^= 0x55
    sdk_port.clearPort()
    sdk_port.writePort(bytes(bad))
    sdk_port.setPacketTimeout(6)
    rx, result = PH.rxPacket(sdk_port)
    assert result == sdk.COMM_SUCCESS
    assert rx[2] == 15 and rx[4] == sdk.protocol1_packet_handler.ERRBIT_CHECKSUM
    # broadcast: applied everywhere, answered nowhere
    assert PH.write1ByteTxOnly(sdk_port, sdk.BROADCAST_ID, 25, 0) == sdk.COMM_SUCCESS
    for sid in IDS:
        value, result, error = PH.read1ByteTxRx(sdk_port, sid, 25)
        ok(result, error)
        assert value == 0


def test_a_client_at_the_wrong_baud_rate_gets_nothing(served):
    port = sdk.PortHandler(served.device)
    assert port.openPort()
    try:
        assert port.setBaudRate(57_600)  # the servos are at 1 Mbps
        _, result, _ = PH.ping(port, 10)
        assert result == sdk.COMM_RX_TIMEOUT
    finally:
        port.closePort()


def test_snakebot_client_over_the_pty(served):
    with DxlClient(served.device) as c:
        assert c.ping(16).id == 16
        c.write_u16(16, 32, 222)
        assert c.read_u16(16, 32) == 222
        c.sync_write(25, 1, {sid: b"\x01" for sid in IDS})
        assert [c.read_u8(sid, 25) for sid in IDS] == [1, 1, 1, 1]


def test_pings_that_reach_the_server_together_do_not_talk_over_their_replies():
    # A client's PINGs pile up in the terminal while the server (or the kernel's tty
    # work) is scheduled late; here twelve come in one write. Back to back on the wire,
    # the ninth would start within servo 1's Return Delay Time and collide with its
    # reply (a busy machine's --bauds all scan lost every servo so). Each goes once the
    # replies to those before it are in: all three replies come back whole.
    ids = range(1, 13)
    delay_us = 508
    assert len(ids) * len(P.ping(1)) * 10 > delay_us  # at 1 Mbps: 10 us a byte
    bus = SimOptions.from_query(f"ids=1,2,3&return_delay={delay_us}").build_bus()
    with PtyServer(bus) as server, open_port(server.device, 1_000_000, timeout=0) as port:
        port.write(b"".join(P.ping(i) for i in ids))
        heard = b""
        deadline = time.monotonic() + 0.5
        while len(heard) < 3 * 6 and time.monotonic() < deadline:
            port.timeout = deadline - time.monotonic()
            heard += port.read(3 * 6 - len(heard))
        collisions = bus.stats.collisions
    assert heard == b"".join(P.status(i, 0, b"") for i in (1, 2, 3))
    assert collisions == 0


def test_snakebot_sim_bus_serves_a_pty_until_interrupted(tmp_path):
    link = tmp_path / "ttyDXL"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "snakebot",
            "sim",
            "bus",
            "--robot",
            "snake5",
            "--pty",
            "--link",
            str(link),
            "--return-delay",
            "0",
            "--json",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        info = json.loads(proc.stdout.readline())
        assert info["ids"] == list(IDS) and info["model"] == "AX-12A"
        assert os.path.realpath(link) == info["device"]
        with DxlClient(str(link)) as c:
            assert c.model_number(10) == 12
            assert c.read_u8(10, 5) == 0  # Return Delay Time as asked
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 130
        assert not link.exists()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()


def test_snakebot_sim_bus_refuses_clashing_options():
    proc = subprocess.run(
        [sys.executable, "-m", "snakebot", "sim", "bus", "--connect"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: --connect needs --unix PATH")
