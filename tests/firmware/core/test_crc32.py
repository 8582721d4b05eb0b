"""The C core's CRC-32 (gait-table checksum) against zlib's, incrementally too."""

import zlib

from hypothesis import given
from hypothesis import strategies as st

from snakebot.core import ffi, lib


@given(st.binary(max_size=2048))
def test_crc32_matches_zlib(data):
    assert lib.crc32_compute(ffi.from_buffer(data), len(data)) == zlib.crc32(data)


@given(st.binary(max_size=512), st.binary(max_size=512))
def test_crc32_is_incremental(head, tail):
    state = lib.crc32_update(lib.CRC32_INIT, ffi.from_buffer(head), len(head))
    state = lib.crc32_update(state, ffi.from_buffer(tail), len(tail))
    assert lib.crc32_final(state) == zlib.crc32(head + tail)


def test_crc32_check_value():
    # The standard check value of CRC-32/ISO-HDLC.
    assert lib.crc32_compute(b"123456789", 9) == 0xCBF43926
