"""QEMU's machine protocol as snakebot.sim.qemu speaks it: each command gets its own
answer, whatever else is waiting on the socket. A reply left unread once shifted every
later answer by one (a fault campaign then read its uptime from the table length it had
asked for just before); the client now takes only the reply that carries its command's
id."""

from __future__ import annotations

import pytest
from firmware_support import APP_BASE, QEMU_DIR, build_firmware

from snakebot.sim.qemu import QemuFirmware

pytestmark = pytest.mark.qemu


@pytest.fixture(scope="module")
def image() -> bytes:
    build_firmware()
    return (QEMU_DIR / "firmware.bin").read_bytes()


def test_an_answer_left_unread_does_not_answer_the_next_command(image: bytes):
    with QemuFirmware(QEMU_DIR / "flash.bin", extra_args=["-name", "answers"]) as fw:
        for _ in range(3):  # three answers no one waits for (the session's private socket)
            fw._qmp_box[0].send_only("cont")
        assert fw.monitor("info name").strip() == "answers"
        assert fw.read_word(APP_BASE) == int.from_bytes(image[0:4], "little")
        assert fw.read_word(APP_BASE + 4) == int.from_bytes(image[4:8], "little")


def test_a_refused_command_is_an_error_and_the_next_one_is_answered(image: bytes):
    with QemuFirmware(QEMU_DIR / "flash.bin", extra_args=["-name", "refused"]) as fw:
        with pytest.raises(Exception, match="QEMU refused human-monitor-command"):
            fw._qmp_box[0].execute("human-monitor-command", {"no-such-argument": 1})
        assert fw.monitor("info name").strip() == "refused"


def test_a_read_across_words_gives_exactly_the_bytes_asked(image: bytes):
    """Unaligned start and end, several monitor lines (xp prints four words a line)."""
    with QemuFirmware(QEMU_DIR / "flash.bin", extra_args=["-name", "bytes"]) as fw:
        assert fw.read(APP_BASE + 3, 37) == image[3:40]
        assert fw.read(APP_BASE, 4096) == image[:4096]
