"""Both codecs against the shared byte-exact vectors in protocol/vectors/."""

from __future__ import annotations

import pytest
from protocol_support import C_BUILDERS, CParser, c_encode, expected_events, load_vectors

from snakebot.formats import protocol
from snakebot.formats.protocol import PacketParser, decode

VECTORS = load_vectors()
IDS = [f"{v['file']}:{v['name']}" for v in VECTORS]
BUILT = [v for v in VECTORS if "build" in v]
BUILT_IDS = [f"{v['file']}:{v['name']}" for v in BUILT]


def test_vectors_cover_every_instruction_and_error_bit():
    builders = {v["build"]["builder"] for v in BUILT}
    assert builders >= {
        "ping",
        "read",
        "write",
        "reg_write",
        "action",
        "reset",
        "sync_write",
        "bulk_read",
        "status",
    }
    error_bytes = {v["build"]["args"]["error"] for v in BUILT if v["build"]["builder"] == "status"}
    assert all(1 << bit in error_bytes for bit in range(7))
    rejected = {e["rejected"] for v in VECTORS for e in v["events"] if "rejected" in e}
    assert rejected == {"checksum", "length"}


@pytest.mark.parametrize("vector", VECTORS, ids=IDS)
def test_python_parser_whole_stream(vector):
    parser = PacketParser()
    assert parser.feed(bytes.fromhex(vector["stream"])) == expected_events(vector)
    assert parser.pending == vector["pending"]


@pytest.mark.parametrize("vector", VECTORS, ids=IDS)
def test_python_parser_byte_by_byte(vector):
    parser = PacketParser()
    events = []
    for byte in bytes.fromhex(vector["stream"]):
        events += parser.feed(bytes((byte,)))
    assert events == expected_events(vector)
    assert parser.pending == vector["pending"]


@pytest.mark.parametrize("vector", VECTORS, ids=IDS)
def test_c_parser(vector):
    stream = bytes.fromhex(vector["stream"])
    polled = CParser()
    assert polled.feed(stream) == expected_events(vector)
    assert polled.pending == vector["pending"]
    lazy = CParser()
    assert lazy.feed_unpolled(stream) == expected_events(vector)
    assert lazy.pending == vector["pending"]


def _python_build(builder: str, args: dict) -> bytes:
    args = dict(args)
    for key in ("data", "params"):
        if isinstance(args.get(key), str):
            args[key] = bytes.fromhex(args[key])
    if builder == "sync_write":
        args["data"] = {i: bytes.fromhex(h) for i, h in args["data"]}
    if builder == "bulk_read":
        args["requests"] = [tuple(r) for r in args["requests"]]
    return getattr(protocol, builder)(**args)


@pytest.mark.parametrize("vector", BUILT, ids=BUILT_IDS)
def test_python_builders(vector):
    wire = bytes.fromhex(vector["stream"])
    assert _python_build(vector["build"]["builder"], vector["build"]["args"]) == wire
    (expected,) = expected_events(vector)
    assert decode(wire) == expected
    assert expected.encode() == wire
    assert protocol.checksum(wire[2:-1]) == wire[-1]


@pytest.mark.parametrize(
    "vector",
    [v for v in BUILT if v["build"]["builder"] in C_BUILDERS],
    ids=[i for v, i in zip(BUILT, BUILT_IDS, strict=True) if v["build"]["builder"] in C_BUILDERS],
)
def test_c_builders(vector):
    wire = bytes.fromhex(vector["stream"])
    assert c_encode(vector["build"]["builder"], vector["build"]["args"]) == wire
