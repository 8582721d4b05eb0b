"""Helpers shared by the protocol tests: the shared vectors, and the C codec driven
through snakebot.core, with events in the same shape as the Python parser's."""

from __future__ import annotations

import importlib.util
import json
from collections.abc import Iterable, Iterator
from pathlib import Path

from snakebot.core import ffi, lib
from snakebot.formats.protocol import Packet, Rejected
from snakebot.paths import REPO_ROOT, protocol_dir

VECTOR_FILES = ("instructions.json", "status.json", "streams.json")


def gen_headers():
    """protocol/gen_headers.py as a module (it is a script, not part of the package)."""
    path = REPO_ROOT / "protocol" / "gen_headers.py"
    spec = importlib.util.spec_from_file_location("gen_headers", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def load_vectors() -> list[dict]:
    vectors = []
    for name in VECTOR_FILES:
        doc = json.loads((Path(protocol_dir()) / "vectors" / name).read_text())
        for vector in doc["vectors"]:
            vectors.append({"file": name, **vector})
    return vectors


def expected_events(vector: dict) -> list[Packet | Rejected]:
    events: list[Packet | Rejected] = []
    for event in vector["events"]:
        if "packet" in event:
            p = event["packet"]
            events.append(Packet(p["id"], p["code"], bytes.fromhex(p["params"])))
        else:
            events.append(Rejected(event["rejected"], bytes.fromhex(event["data"])))
    return events


_REASONS = {lib.DXL_EVENT_BAD_CHECKSUM: "checksum", lib.DXL_EVENT_BAD_LENGTH: "length"}


class CParser:
    """The C parser (firmware/core/dxl_parser.c) with the Python parser's interface."""

    def __init__(self) -> None:
        self._parser = ffi.new("dxl_parser *")
        self._event = ffi.new("dxl_event *")
        lib.dxl_parser_reset(self._parser)

    @property
    def pending(self) -> int:
        return lib.dxl_parser_pending(self._parser)

    def _drain(self) -> Iterator[Packet | Rejected]:
        ev = self._event
        while lib.dxl_parser_poll(self._parser, ev):
            raw = bytes(ffi.buffer(ev.raw, ev.raw_len))
            if ev.kind == lib.DXL_EVENT_PACKET:
                params = bytes(ffi.buffer(ev.params, ev.nparams)) if ev.nparams else b""
                assert raw[2] == ev.id and raw[4] == ev.code and raw[5:-1] == params
                yield Packet(ev.id, ev.code, params)
            else:
                assert raw[2] == ev.id
                yield Rejected(_REASONS[ev.kind], raw)

    def feed(self, data: bytes) -> list[Packet | Rejected]:
        """Feed byte by byte, draining the events after each byte (the firmware's way)."""
        events: list[Packet | Rejected] = []
        for byte in data:
            assert lib.dxl_parser_feed(self._parser, byte)
            events.extend(self._drain())
        return events

    def feed_unpolled(self, data: Iterable[int]) -> list[Packet | Rejected]:
        """Feed as many bytes as the parser takes before polling (a lazy main loop)."""
        events: list[Packet | Rejected] = []
        for byte in data:
            if not lib.dxl_parser_feed(self._parser, byte):
                events.extend(self._drain())
                assert lib.dxl_parser_feed(self._parser, byte)
        events.extend(self._drain())
        return events


def c_encode(builder: str, args: dict) -> bytes:
    """Run one of the C builders on a vector's arguments; b"" if it returned 0."""
    cap = 260
    out = ffi.new(f"uint8_t[{cap}]")
    if builder == "ping":
        n = lib.dxl_ping(out, cap, args["id"])
    elif builder == "action":
        n = lib.dxl_action(out, cap, args["id"])
    elif builder == "read":
        n = lib.dxl_read(out, cap, args["id"], args["address"], args["length"])
    elif builder in ("write", "reg_write"):
        data = bytes.fromhex(args["data"])
        fn = lib.dxl_write if builder == "write" else lib.dxl_reg_write
        n = fn(out, cap, args["id"], args["address"], data, len(data))
    elif builder == "status":
        params = bytes.fromhex(args["params"])
        n = lib.dxl_status(out, cap, args["id"], args["error"], params or ffi.NULL, len(params))
    elif builder == "sync_write":
        ids = bytes(i for i, _ in args["data"])
        data = b"".join(bytes.fromhex(h) for _, h in args["data"])
        n = lib.dxl_sync_write(out, cap, args["address"], args["length"], ids, data, len(ids))
    else:
        raise KeyError(builder)
    return bytes(out[0:n])


C_BUILDERS = {"ping", "action", "read", "write", "reg_write", "status", "sync_write"}
