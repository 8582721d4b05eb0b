"""Long upload chunks through window page Upload Data 2: one WRITE at Upload Offset runs
on through Upload Data and Window Page into the window, and the controller's C device
logic stages the window's bytes right after Upload Data's, checking the WRITE as a whole."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from ctl_support import CTL, CTL_ID, Device, gait_tables
from hypothesis import given, settings
from hypothesis import strategies as st

from snakebot.core import lib
from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import ErrorFlags, write
from snakebot.formats.upload_writes import LONG_CHUNK_PAGE, chunk_limit, chunk_writes
from snakebot.link.controller import ControllerErrors, UploadResult

PAGE = CTL.page(LONG_CHUNK_PAGE)
OFFSET = CTL.register("Upload Offset")
DATA = CTL.register("Upload Data")
SELECTOR = CTL.register("Window Page")
LONG = chunk_limit(CTL, long_chunks=True)


@pytest.fixture
def dev() -> Device:
    return Device()


def send(dev: Device, writes: list[tuple[int, bytes]]) -> None:
    for address, payload in writes:
        assert dev.one(write(CTL_ID, address, payload)).error == 0


def commit(dev: Device, data: bytes) -> int:
    assert dev.commit(len(data), zlib.crc32(data)) == 0
    return dev.get("Upload Result")


def long_write(at: int, piece: bytes, page: int = PAGE.number) -> bytes:
    """The WRITE payload of a long chunk (at Upload Offset), Window Page = ``page``."""
    return OFFSET.encode(at) + piece[: DATA.size] + SELECTOR.encode(page) + piece[DATA.size :]


def test_a_long_chunk_fills_upload_data_and_the_whole_window():
    assert LONG == DATA.size + CTL.servo_records * CTL.servo_record_size
    # the WRITE fits one Protocol 1.0 packet the controller's parser takes
    packet = write(CTL_ID, OFFSET.address, long_write(0, bytes(LONG)))
    assert len(packet) <= lib.DXL_MAX_PACKET


@settings(max_examples=25, deadline=None)
@given(gait_tables(max_joints=18), st.integers(1, LONG))
def test_any_valid_table_uploads_in_any_long_chunk_size(t, chunk):
    dev = Device()
    data = t.encode()
    send(dev, chunk_writes(data, chunk, CTL, long_chunks=True))
    assert commit(dev, data) == UploadResult.OK
    assert dev.get("Table CRC") == t.image_crc


def wave(frames: int) -> bytes:
    """The bytes of a 4-joint table of ``frames`` frames."""
    k = np.arange(frames)[:, None]
    ticks = 512 + np.round(200 * np.sin(k / 7 + np.arange(4))).astype(int)
    return GaitTable((10, 11, 15, 16), 20, True, ((200, 824),) * 4, ticks, {}).encode()


def test_long_and_short_chunks_mix(dev):
    """An old host's 64-byte chunks still work with the window on page 19."""
    data = wave(200)
    send(dev, chunk_writes(data[:LONG], controller=CTL, long_chunks=True))
    assert dev.get("Window Page") == PAGE.number
    rest = [
        (a, OFFSET.encode(LONG + int.from_bytes(p[:2], "little")) + p[2:])
        for a, p in chunk_writes(data[LONG:], controller=CTL)
    ]
    send(dev, rest)
    assert commit(dev, data) == UploadResult.OK


def test_the_window_continues_upload_data_at_the_offset(dev):
    """Window byte i goes to staging[Upload Offset + 64 + i], also written on its own."""
    data = wave(200)
    at = 100
    damaged = data[: at + DATA.size] + bytes(LONG - DATA.size) + data[at + LONG :]
    send(dev, chunk_writes(damaged, controller=CTL, long_chunks=True))
    assert commit(dev, data) == UploadResult.TRANSFER_CRC
    assert dev.set("Upload Offset", at) == 0
    window = SELECTOR.encode(PAGE.number) + data[at + DATA.size : at + LONG]
    assert dev.one(write(CTL_ID, SELECTOR.address, window)).error == 0
    assert commit(dev, data) == UploadResult.OK


def test_page_19_reads_as_zeros(dev):
    send(dev, chunk_writes(b"\xa5" * LONG, controller=CTL, long_chunks=True))
    window = dev.read(PAGE.base, CTL.servo_records * CTL.servo_record_size)
    assert window == bytes(len(window))


def test_a_long_chunk_needs_the_page_in_the_same_write(dev):
    """On another page the window bytes are that page's: the Program page's are
    read-only, so the whole WRITE is refused and nothing of it staged."""
    program = CTL.page("Program").number
    data = bytes(LONG)
    reply = dev.one(write(CTL_ID, OFFSET.address, long_write(0, data, page=program)))
    assert reply.error == ErrorFlags.RANGE
    assert dev.get("Window Page") == 0
    assert commit(dev, data) == UploadResult.INCOMPLETE  # not even Upload Data's part


def test_a_long_chunk_past_the_capacity_is_refused_whole(dev):
    data = wave(100)
    lib.ctl_set_capacity(dev.d, len(data))
    last = len(data) - LONG
    send(dev, chunk_writes(data[:last], controller=CTL, long_chunks=True))
    too_far = long_write(last + 1, data[last + 1 :] + b"\x00")  # one byte past
    assert dev.one(write(CTL_ID, OFFSET.address, too_far)).error == ErrorFlags.RANGE
    assert dev.flags & ControllerErrors.UPLOAD_LENGTH
    assert commit(dev, data) == UploadResult.INCOMPLETE  # the refused chunk staged nothing
    assert dev.one(write(CTL_ID, OFFSET.address, long_write(last, data[last:]))).error == 0
    assert commit(dev, data) == UploadResult.OK
