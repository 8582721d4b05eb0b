"""`snakebot upload` as one stream (checks, chunks, commit, verification) into the real
firmware image under QEMU: the largest table lands in one attempt and the report, over a
link QEMU does not pace, gives no share of the wire; a check that fails while the chunks
are in flight leaves the firmware's active table as it was."""

from __future__ import annotations

import zlib

import pytest
from controller_cli_support import cli, cli_json, constant_table, save, wave_table
from firmware_support import CONTROLLER_ID, board_value, booted_qemu, client

from snakebot.formats.gaittable import max_frames
from snakebot.link.controller import load

pytestmark = [pytest.mark.qemu, pytest.mark.timeout(300)]

CTL = load()
LARGEST = max_frames(4, board_value("qemu", "BOARD_TABLE_CAPACITY"))  # QEMU's own


@pytest.fixture(scope="module")
def firmware(tmp_path_factory):
    with booted_qemu(tmp_path_factory.mktemp("bus")) as port:
        yield port


def active_crc(port: str) -> int:
    crc = CTL.register("Table CRC")
    with client(port) as c:
        return int.from_bytes(c.read(CONTROLLER_ID, crc.address, crc.size), "little")


def test_the_largest_table_in_one_stream_says_the_link_is_not_paced(firmware, tmp_path):
    path = save(wave_table(frames=LARGEST), tmp_path)
    report = cli_json("upload", path, "--port", firmware)
    assert report["crc"] == f"0x{zlib.crc32(path.read_bytes()):08x}"
    assert report["attempts"] == 1
    # QEMU moves the bytes faster than 57600 baud would: no percentage, and it says so.
    # On a machine too busy to keep QEMU that fast the link is slower than the wire,
    # and the report must then say it was paced and give the share.
    wire_s = report["sent_bytes"] * 10 / report["baudrate"]
    assert report["paced"] is (report["seconds"] >= wire_s)
    assert ("wire_percent" in report) is report["paced"]
    assert active_crc(firmware) == zlib.crc32(path.read_bytes())


def test_a_failing_check_with_chunks_in_flight_keeps_the_firmwares_table(firmware, tmp_path):
    kept = save(wave_table(frames=LARGEST), tmp_path, "kept.gait")
    assert cli("upload", kept, "--port", firmware).exit_code == 0
    strangers = save(constant_table(512, ids=(1, 2, 3, 4), frames=250), tmp_path)
    result = cli("upload", strangers, "--port", firmware)
    assert result.exit_code == 2  # a table for other servos: bad input (UploadRefused)
    assert "which the controller does not have" in result.stderr
    assert active_crc(firmware) == zlib.crc32(kept.read_bytes())
    # the link is clean for the next command
    assert cli("upload", kept, "--port", firmware).exit_code == 0
