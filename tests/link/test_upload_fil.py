"""`snakebot upload` as one stream (checks, chunks, commit, verification) into the real
firmware image on both boards (the CM-530's on the emulated STM32F103RE, the qemu
board's under QEMU): the board's largest table lands in one attempt and the report says
whether the link was paced (QEMU's pty is not: no share of the wire; the emulated
USART3 moves bytes at 57600 baud: the share); a check that fails while the chunks are in
flight leaves the firmware's active table as it was, if the table is one an upload
never displaces (the CM-530's largest give way to the chunks that reach them, as
protocol/controller.md says: tests/firmware/core/test_big_tables.py)."""

from __future__ import annotations

import zlib

import pytest
from controller_cli_support import cli, cli_json, constant_table, save, wave_table
from firmware_support import BOARDS, CONTROLLER_ID, board_value, booted, client, kept_capacity

from snakebot.formats.gaittable import max_frames
from snakebot.link.controller import load

pytestmark = [pytest.mark.qemu, pytest.mark.timeout(300)]

CTL = load()


@pytest.fixture(scope="module", params=BOARDS)
def firmware(request, tmp_path_factory):
    """The board's name and PC link."""
    with booted(request.param, tmp_path_factory.mktemp("bus")) as port:
        yield request.param, port


def largest(board: str) -> int:
    """The frames of 4 servos the board's largest table holds."""
    return max_frames(4, board_value(board, "BOARD_TABLE_CAPACITY"))


def active_crc(port: str) -> int:
    crc = CTL.register("Table CRC")
    with client(port) as c:
        return int.from_bytes(c.read(CONTROLLER_ID, crc.address, crc.size), "little")


def test_the_largest_table_in_one_stream_says_whether_the_link_was_paced(firmware, tmp_path):
    board, firmware = firmware
    path = save(wave_table(frames=largest(board)), tmp_path)
    report = cli_json("upload", path, "--port", firmware)
    assert report["crc"] == f"0x{zlib.crc32(path.read_bytes()):08x}"
    assert report["attempts"] == 1
    # QEMU moves the bytes faster than 57600 baud would: no percentage, and it says so.
    # On a machine too busy to keep QEMU that fast the link is slower than the wire,
    # and the report must then say it was paced and give the share; the emulated CM-530
    # moves them at the wire's rate, so its report always does.
    wire_s = report["sent_bytes"] * 10 / report["baudrate"]
    assert report["paced"] is (report["seconds"] >= wire_s)
    assert ("wire_percent" in report) is report["paced"]
    assert active_crc(firmware) == zlib.crc32(path.read_bytes())


def refused_upload(port: str, tmp_path) -> None:
    """An upload for servos the controller does not have, refused by the check the host
    makes while the chunks are in flight."""
    strangers = save(constant_table(512, ids=(1, 2, 3, 4), frames=250), tmp_path)
    result = cli("upload", strangers, "--port", port)
    assert result.exit_code == 2  # a table for other servos: bad input (UploadRefused)
    assert "which the controller does not have" in result.stderr


def test_a_failing_check_with_chunks_in_flight_keeps_the_firmwares_table(firmware, tmp_path):
    board, firmware = firmware
    frames = max_frames(4, kept_capacity(board))  # the largest no upload displaces
    kept = save(wave_table(frames=frames), tmp_path, "kept.gait")
    assert cli("upload", kept, "--port", firmware).exit_code == 0
    refused_upload(firmware, tmp_path)
    assert active_crc(firmware) == zlib.crc32(kept.read_bytes())
    # the link is clean for the next command
    assert cli("upload", kept, "--port", firmware).exit_code == 0
