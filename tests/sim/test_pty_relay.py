"""The relay between QEMU's socket and a pseudo-terminal (snakebot.sim.transports.relay):
bytes a client writes reach QEMU no faster than the line's rate, where one is given (a
client writing without pause once reached the firmware in QEMU some 40 times faster than
the PC link's 57600 baud, and its replies starved the control loop, which no board sees)."""

from __future__ import annotations

import os
import pty
import socket
import time
import tty

from snakebot.facts.boards import PC_LINK_BAUD
from snakebot.sim.bus.clock import BITS_PER_BYTE
from snakebot.sim.transports.relay import PtyRelay

SENT = 1152  # bytes: 0.2 s at 57600 baud


def arrival_s(rate: float | None) -> float:
    """Seconds until SENT bytes written at once to the terminal have all reached QEMU's
    end of the socket pair through a relay at ``rate``."""
    master, slave = pty.openpty()
    tty.setraw(slave)
    qemu, ours = socket.socketpair()
    relay = PtyRelay(ours, master, "test-relay", rate).start()
    try:
        start = time.monotonic()
        os.write(slave, bytes(SENT))
        got = 0
        qemu.settimeout(5.0)
        while got < SENT:
            got += len(qemu.recv(4096))
        return time.monotonic() - start
    finally:
        relay.stop()
        qemu.close()
        os.close(slave)
        os.close(master)


def test_the_pc_link_reaches_qemu_at_its_line_rate():
    rate = PC_LINK_BAUD / BITS_PER_BYTE
    wire_s = SENT / rate
    paced = arrival_s(rate)
    assert paced >= 0.9 * wire_s, (
        f"{SENT} bytes in {paced * 1e3:.0f} ms, the wire takes {wire_s * 1e3:.0f}"
    )
    assert paced < wire_s + 0.5  # and not much slower


def test_without_a_rate_bytes_go_as_qemu_takes_them():
    assert arrival_s(None) < 0.5 * SENT / (PC_LINK_BAUD / BITS_PER_BYTE)
