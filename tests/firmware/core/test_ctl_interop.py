"""Any Protocol 1.0 client can drive the controller: ROBOTIS's own dynamixel-sdk talks to
the C core (ctl_device) over a real pseudo-terminal, pings it, reads its identity,
uploads a gait table through the window, commits and starts it."""

from __future__ import annotations

import os
import select
import threading
import tty
import zlib

import numpy as np
import pytest
from ctl_support import CTL, CTL_ID, Device

from snakebot.formats.gaittable import GaitTable
from snakebot.link.controller import State, UploadResult

dynamixel_sdk = pytest.importorskip("dynamixel_sdk")

REPLY_TIMEOUT_S = 5.0


class PatientPort(dynamixel_sdk.PortHandler):
    """The SDK's port with a generous reply timeout: the machine is shared and the reply
    comes from a Python thread; this test checks behaviour, not speed."""

    def setPacketTimeout(self, packet_length):  # noqa: N802 - the SDK's name
        self.setPacketTimeoutMillis(REPLY_TIMEOUT_S * 1000)


class PtyController:
    """A ctl_device behind a pseudo-terminal, served by a thread (stopped on close)."""

    def __init__(self) -> None:
        self.device = Device()
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if ready:
                data = os.read(self.master, 512)
                reply = self.device.feed(data)
                if reply:
                    os.write(self.master, reply)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        os.close(self.master)
        os.close(self.slave)


@pytest.fixture
def controller():
    c = PtyController()
    yield c
    c.close()


def test_dynamixel_sdk_drives_the_controller(controller):
    port = PatientPort(controller.path)
    assert port.openPort() and port.setBaudRate(57600)
    ph = dynamixel_sdk.PacketHandler(1.0)
    ok = dynamixel_sdk.COMM_SUCCESS
    try:
        model, result, error = ph.ping(port, CTL_ID)
        assert (result, error, model) == (ok, 0, CTL.model_number)

        table = GaitTable(
            (1, 2, 3, 4),
            20,
            True,
            ((100, 900),) * 4,
            np.random.default_rng(3).integers(100, 901, size=(150, 4)),
        ).encode()
        offset = CTL.register("Upload Offset").address
        for at in range(0, len(table), 64):
            chunk = list(at.to_bytes(2, "little") + table[at : at + 64])
            result, error = ph.writeTxRx(port, CTL_ID, offset, len(chunk), chunk)
            assert (result, error) == (ok, 0)
        commit = list(len(table).to_bytes(2, "little") + zlib.crc32(table).to_bytes(4, "little"))
        start = CTL.register("Upload Length").address
        assert ph.writeTxRx(port, CTL_ID, start, 7, commit + [1]) == (ok, 0)
        result_reg = CTL.register("Upload Result").address
        value, result, error = ph.read1ByteTxRx(port, CTL_ID, result_reg)
        assert (value, result, error) == (UploadResult.OK, ok, 0)
        crc, result, error = ph.read4ByteTxRx(port, CTL_ID, CTL.register("Table CRC").address)
        assert crc == zlib.crc32(table)

        command = CTL.register("Command").address
        assert ph.write1ByteTxRx(port, CTL_ID, command, CTL.enums["Command"]["PLAY"]) == (ok, 0)
        state, result, error = ph.read1ByteTxRx(port, CTL_ID, CTL.register("State").address)
        assert state == State.PLAYING
        # an out-of-range value comes back as a range error, as from a servo
        result, error = ph.write2ByteTxRx(port, CTL_ID, CTL.register("Speed Scale").address, 5000)
        assert result == ok and error == 8
    finally:
        port.closePort()
