"""A client that floods the emulated CM-530's PC link faster than its 57600 baud line
meets the terminal's back-pressure, as behind a USB adapter: the emulator takes at most
``PC_BACKLOG`` bytes ahead of USART3's receiver, the writer's writes then block (here:
EAGAIN), and the firmware still answers once the flood stops."""

from __future__ import annotations

import os
import termios
import time

import pytest
from firmware_support import cm530_image, wait_for_boot

from snakebot.sim.mcu.runner import PC_BACKLOG, McuFirmware

pytest.importorskip("unicorn")
pytestmark = [pytest.mark.qemu]  # real time, beside the other emulated boards

FLOOD_S = 1.0


def test_a_flood_on_the_pc_link_is_held_back_not_queued() -> None:
    with McuFirmware(cm530_image()) as fw:
        wait_for_boot(fw.pc_link)
        fd = os.open(fw.pc_link, os.O_WRONLY | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            attrs = termios.tcgetattr(fd)
            attrs[4] = attrs[5] = termios.B57600  # USART3's rate: else the bytes are dropped
            termios.tcsetattr(fd, termios.TCSANOW, attrs)
            junk = bytes(range(1, 256)) * 16  # no packet header: the firmware drops it
            written = blocked = 0
            most_queued = 0
            end = time.monotonic() + FLOOD_S
            while time.monotonic() < end:
                try:
                    written += os.write(fd, junk)
                except BlockingIOError:
                    blocked += 1
                    time.sleep(0.001)
                most_queued = max(most_queued, fw.board.mcu.usart3.inbox)
        finally:
            os.close(fd)
        line_bytes = 57600 / 10 * FLOOD_S
        assert blocked > 0, "the writer never had to wait"
        assert most_queued <= PC_BACKLOG
        # what the writer got rid of: the line's bytes, the backlog and the terminal's
        # buffer (a few KB), not the megabytes an unbounded queue would take
        assert written < line_bytes + PC_BACKLOG + 64 * 1024, written
        wait_for_boot(fw.pc_link, timeout=10)  # the flood's tail drained: it answers again
        assert fw.error is None
