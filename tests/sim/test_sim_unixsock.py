"""The emulated bus on a Unix socket, the way QEMU's USART character device reaches it."""

from __future__ import annotations

import shutil
import socket
import time

import pytest

from snakebot.formats import protocol as P
from snakebot.formats.protocol import PacketParser
from snakebot.sim.options import SimOptions
from snakebot.sim.transports import UnixSocketServer


def ask(conn: socket.socket, packet: bytes, expect: int, timeout: float = 2.0) -> bytes:
    """Send ``packet`` and collect ``expect`` bytes of answer."""
    conn.sendall(packet)
    conn.settimeout(timeout)
    got = b""
    while len(got) < expect:
        chunk = conn.recv(expect - len(got))
        if not chunk:
            break
        got += chunk
    return got


def test_a_client_that_connects_to_the_socket_talks_to_the_servos(tmp_path):
    path = tmp_path / "bus.sock"
    bus = SimOptions.from_query("ids=1,2&return_delay=0").build_bus()
    with UnixSocketServer(bus, path) as server:
        for _ in range(2):  # one client after another, as QEMU restarts
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as conn:
                conn.connect(str(path))
                assert ask(conn, P.ping(2), 6) == P.status(2)
                assert ask(conn, P.read(1, 0, 2), 8) == P.status(1, 0, b"\x0c\x00")
                # SYNC_WRITE gets no answer; the servos take it
                conn.sendall(P.sync_write(25, 1, {1: b"\x01", 2: b"\x01"}))
                assert ask(conn, P.read(2, 25, 1), 7) == P.status(2, 0, b"\x01")
        assert server.connections == 2
    assert not path.exists()


def test_the_server_can_connect_to_a_listening_peer(tmp_path):
    path = tmp_path / "qemu.sock"
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as listener:
        listener.bind(str(path))
        listener.listen(1)
        bus = SimOptions.from_query("ids=4&return_delay=0").build_bus()
        with UnixSocketServer(bus, path, connect=True):
            listener.settimeout(5)
            conn, _ = listener.accept()
            with conn:
                events = PacketParser().feed(ask(conn, P.ping(4), 6))
                assert [e.id for e in events] == [4]


QEMU_IMAGE_NEEDED = "build/qemu/flash.bin (make firmware) and qemu-system-arm"


@pytest.mark.qemu
def test_qemu_connects_its_usart1_to_the_bus_socket(tmp_path):
    from snakebot.sim.qemu import DEFAULT_IMAGE, Endpoint, QemuFirmware

    if not DEFAULT_IMAGE.exists() or shutil.which("qemu-system-arm") is None:
        pytest.skip(f"needs {QEMU_IMAGE_NEEDED}")
    path = tmp_path / "bus.sock"
    bus = SimOptions.from_query("robot=snake5").build_bus()
    with UnixSocketServer(bus, path) as server:
        with QemuFirmware(bus=Endpoint.unix_client(path)) as firmware:
            deadline = time.monotonic() + 10
            while server.connections == 0 and time.monotonic() < deadline:
                time.sleep(0.05)
            assert server.connections == 1
            assert firmware.running
