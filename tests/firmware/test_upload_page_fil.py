"""Long upload chunks (Upload Data and window page Upload Data 2 in one WRITE) on the real
firmware image on both boards (the CM-530's on the emulated STM32F103RE, the qemu board's
under QEMU), its servo bus corrupted as in the fault campaigns (1 % of the
bytes get a flipped bit): the board's largest table goes in long chunks and lands whole, a long
chunk damaged on the PC link is dropped and the commit says so, and a long chunk that
would pass the staging area is refused whole."""

from __future__ import annotations

import zlib

import pytest
from controller_cli_support import SNAKE5_IDS, cli_json, constant_table, save, wave_table
from firmware_support import BOARDS, CONTROLLER_ID, board_value, booted, client, kept_capacity

from snakebot.formats.gaittable import max_frames
from snakebot.formats.protocol import ErrorFlags, ServoError, write
from snakebot.formats.upload_writes import chunk_limit, chunk_writes, commit_write
from snakebot.link.controller import ControllerErrors, UploadResult, load
from snakebot.sim.bus.faults import FaultConfig

pytestmark = [pytest.mark.qemu, pytest.mark.timeout(300)]

CTL = load()
LONG = chunk_limit(CTL, long_chunks=True)
CORRUPT = 0.01  # the fault campaigns' corrupt-1pct


@pytest.fixture(scope="module", params=BOARDS)
def firmware(request, tmp_path_factory):
    """The board's PC link, and its Table Capacity."""
    faults = FaultConfig(seed=7, corrupt=CORRUPT)
    with booted(request.param, tmp_path_factory.mktemp("bus"), faults=faults) as port:
        yield request.param, port


def test_the_largest_table_uploads_in_long_chunks_on_the_firmware(firmware, tmp_path):
    board, firmware = firmware
    capacity = board_value(board, "BOARD_TABLE_CAPACITY")
    path = save(wave_table(frames=max_frames(4, capacity)), tmp_path)
    crc = zlib.crc32(path.read_bytes())
    for _ in range(2):  # the second replaces the first the same way
        report = cli_json("upload", path, "--port", firmware)
        assert report["chunk_bytes"] == LONG
        assert report["crc"] == f"0x{crc:08x}" and report["bytes"] == path.stat().st_size
        assert report["chunks"] == -(-report["bytes"] // LONG)


def test_a_damaged_long_chunk_is_dropped_and_a_refused_one_stages_nothing(firmware, tmp_path):
    board, firmware = firmware
    # an active table no upload displaces (the CM-530's largest give way to the chunks)
    kept = save(wave_table(frames=max_frames(4, kept_capacity(board))), tmp_path, "kept.gait")
    assert (
        cli_json("upload", kept, "--port", firmware)["crc"]
        == f"0x{zlib.crc32(kept.read_bytes()):08x}"
    )
    capacity = board_value(board, "BOARD_TABLE_CAPACITY")
    # not the table the staging area holds from before: a lost chunk must show
    data = constant_table(600, frames=max_frames(len(SNAKE5_IDS), capacity)).encode()
    writes = chunk_writes(data, controller=CTL, long_chunks=True)
    length = CTL.register("Upload Length").address
    with client(firmware) as c:
        before = c.read(CONTROLLER_ID, CTL.register("Table CRC").address, 4)
        for k, (address, payload) in enumerate(writes):
            if k == 3:  # one bit flipped: the checksum fails, the firmware drops it
                packet = bytearray(write(CONTROLLER_ID, address, payload))
                packet[100] ^= 0x04
                c.port.write(bytes(packet))
                continue
            c.write(CONTROLLER_ID, address, payload)
        c.write(CONTROLLER_ID, *commit_write(data, CTL))
        assert c.read_u8(CONTROLLER_ID, CTL.register("Upload Result").address) in (
            UploadResult.TRANSFER_CRC,
            UploadResult.INCOMPLETE,
        )
        assert c.read(CONTROLLER_ID, CTL.register("Table CRC").address, 4) == before
        # the missing chunk alone completes the staging area: the commit now lands
        c.write(CONTROLLER_ID, *writes[3])
        c.write(CONTROLLER_ID, *commit_write(data, CTL))
        assert c.read_u8(CONTROLLER_ID, CTL.register("Upload Result").address) == UploadResult.OK
        # a long chunk one byte past the staging area is refused whole
        address, payload = writes[-2]
        offset = CTL.register("Upload Offset")
        last = len(data) - LONG + 1
        with pytest.raises(ServoError) as refused:
            c.write(CONTROLLER_ID, address, offset.encode(last) + payload[offset.size :])
        assert refused.value.flags & ErrorFlags.RANGE
        flags = c.read_u16(CONTROLLER_ID, CTL.register("Error Flags").address)
        assert flags & ControllerErrors.UPLOAD_LENGTH
        assert c.read_u16(CONTROLLER_ID, length) == len(data)
