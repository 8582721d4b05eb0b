"""The C codec's own contract: bounded buffer, feed refusal, reset, event views, and
builders that return 0 instead of writing a bad or oversized packet."""

from __future__ import annotations

import pytest

from snakebot.core import ffi, lib
from snakebot.formats.protocol import encode_packet


def _drain(parser, ev):
    events = []
    while lib.dxl_parser_poll(parser, ev):
        events.append((ev.kind, bytes(ffi.buffer(ev.raw, ev.raw_len)), ev))
    return events


def test_feed_refuses_only_when_a_full_packet_waits_unpolled():
    parser, ev = ffi.new("dxl_parser *"), ffi.new("dxl_event *")
    wire = encode_packet(1, 3, bytes(range(244)))  # 250 bytes
    for byte in wire:
        assert lib.dxl_parser_feed(parser, byte)
    assert lib.dxl_parser_pending(parser) == lib.DXL_MAX_PACKET
    assert not lib.dxl_parser_feed(parser, 0xFF)
    assert lib.dxl_parser_poll(parser, ev) and ev.kind == lib.DXL_EVENT_PACKET
    assert ev.nparams == 244 and bytes(ffi.buffer(ev.params, 244)) == bytes(range(244))
    assert lib.dxl_parser_feed(parser, 0xFF)


def test_polled_parser_never_refuses_a_byte():
    # Drained after every byte, at most DXL_MAX_PACKET - 1 bytes ever wait.
    parser, ev = ffi.new("dxl_parser *"), ffi.new("dxl_event *")
    stream = (b"\xff\xff\x00\xf6" + bytes(250)) * 3 + encode_packet(2, 1) * 50
    for byte in stream:
        assert lib.dxl_parser_feed(parser, byte)
        _drain(parser, ev)
        assert lib.dxl_parser_pending(parser) < lib.DXL_MAX_PACKET


def test_event_views_stay_valid_until_the_next_feed():
    parser, ev = ffi.new("dxl_parser *"), ffi.new("dxl_event *")
    first, second = encode_packet(1, 2, b"\x24\x02"), encode_packet(9, 0, b"\xff\x03")
    for byte in first + second:
        lib.dxl_parser_feed(parser, byte)
    got = []
    while lib.dxl_parser_poll(parser, ev):
        got.append((ffi.cast("const uint8_t *", ev.raw), ev.raw_len))
    # Both views are still intact after polling past them.
    assert [bytes(ffi.buffer(ptr, n)) for ptr, n in got] == [first, second]


def test_views_are_contiguous_across_the_ring_wrap():
    parser, ev = ffi.new("dxl_parser *"), ffi.new("dxl_event *")
    wire = encode_packet(5, 3, bytes(range(100, 200)))
    for _ in range(7):  # 7 * 106 bytes: packets start at every phase of the 256-slot ring
        for byte in wire:
            lib.dxl_parser_feed(parser, byte)
        ((kind, raw, _),) = _drain(parser, ev)
        assert kind == lib.DXL_EVENT_PACKET and raw == wire


def test_reset_forgets_a_partial_packet():
    parser, ev = ffi.new("dxl_parser *"), ffi.new("dxl_event *")
    for byte in encode_packet(1, 1)[:4]:
        lib.dxl_parser_feed(parser, byte)
    lib.dxl_parser_reset(parser)
    assert lib.dxl_parser_pending(parser) == 0
    for byte in encode_packet(3, 1):
        lib.dxl_parser_feed(parser, byte)
    ((kind, raw, _),) = _drain(parser, ev)
    assert raw == encode_packet(3, 1)


@pytest.mark.parametrize(
    "call",
    [
        lambda out: lib.dxl_ping(out, 64, 0xFF),
        lambda out: lib.dxl_status(out, 64, 0xFE, 0, ffi.NULL, 0),
        lambda out: lib.dxl_read(out, 64, 1, 30, 0),
        lambda out: lib.dxl_write(out, 64, 1, 30, ffi.NULL, 0),
        lambda out: lib.dxl_encode(out, 64, 1, 3, ffi.NULL, 2),
        lambda out: lib.dxl_encode(out, 300, 1, 3, bytes(245), 245),
        lambda out: lib.dxl_sync_write(out, 64, 30, 2, b"\x01", ffi.NULL, 1),
        lambda out: lib.dxl_sync_write(out, 64, 30, 2, b"\xfe", b"\x00\x00", 1),
        lambda out: lib.dxl_sync_write(out, 64, 30, 2, b"\x01\x02", bytes(4), 0),
        lambda out: lib.dxl_ping(out, 5, 1),  # a ping is 6 bytes
        lambda out: lib.dxl_sync_write(out, 64, 30, 200, bytes(2), bytes(400), 2),
    ],
)
def test_builders_return_zero_for_invalid_or_oversized(call):
    out = ffi.new("uint8_t[300]")
    assert call(out) == 0


def test_builders_never_write_past_capacity():
    out = ffi.new("uint8_t[32]", [0xA5] * 32)
    assert lib.dxl_write(out, 10, 1, 30, bytes(4), 4) == 0  # needs 6 + 5 bytes
    assert list(out[0:32]) == [0xA5] * 32
    assert lib.dxl_write(out, 11, 1, 30, bytes(4), 4) == 11
    assert list(out[11:32]) == [0xA5] * 21
