"""The WRITEs that upload a gait table to the controller (protocol/controller.md,
"Uploading a gait table"), as (address, data) pairs any Protocol 1.0 client can send.

The transport (retries, timeouts, progress) belongs to the upload command; this module
only knows the layout, so the addresses come from the controller's description and nowhere else.
"""

from __future__ import annotations

import zlib

from snakebot.facts.controller import Controller, ControllerTableError, load

LONG_CHUNK_PAGE = "Upload Data 2"
"""The window page whose bytes continue Upload Data: a WRITE at Upload Offset that runs on
through Window Page (set to this page) into the window carries one long chunk."""


def chunk_limit(controller: Controller | None = None, *, long_chunks: bool = False) -> int:
    """The most table bytes one chunk WRITE carries: Upload Data's size, plus the window's
    when ``long_chunks`` (the controller has the page :data:`LONG_CHUNK_PAGE`)."""
    ctl = controller or load()
    data = ctl.register("Upload Data")
    if not long_chunks:
        return data.size
    selector = ctl.register("Window Page")
    page = ctl.page(LONG_CHUNK_PAGE)
    (more,) = page.fields
    if not (data.end == selector.address and selector.end == page.base + more.address):
        raise ControllerTableError(
            f"the controller's description: Upload Data, Window Page and {LONG_CHUNK_PAGE} "
            "must be adjacent for long chunks"
        )
    return data.size + more.size


def chunk_writes(
    table: bytes,
    chunk: int | None = None,
    controller: Controller | None = None,
    *,
    long_chunks: bool = False,
) -> list[tuple[int, bytes]]:
    """One WRITE per chunk: at Upload Offset, the chunk's offset (2 bytes) then its bytes.
    The first chunk is at offset 0 (which starts an upload on the controller). With
    ``long_chunks`` a chunk may pass Upload Data's size: its WRITE then carries the
    Window Page byte (:data:`LONG_CHUNK_PAGE`) between Upload Data's bytes and the rest."""
    ctl = controller or load()
    limit = chunk_limit(ctl, long_chunks=long_chunks)
    size = limit if chunk is None else chunk
    if not 1 <= size <= limit:
        raise ControllerTableError(f"upload chunk must be 1..{limit} bytes, got {size}")
    capacity = ctl.limits["max_table_bytes"]
    if not 1 <= len(table) <= capacity:
        raise ControllerTableError(
            f"a table of {len(table)} bytes cannot be uploaded: the controller holds 1.."
            f"{capacity} bytes; use fewer frames"
        )
    offset = ctl.register("Upload Offset")
    window = ctl.register("Upload Data").size
    writes = []
    for at in range(0, len(table), size):
        piece = table[at : at + size]
        if len(piece) > window:
            page = ctl.register("Window Page").encode(ctl.page(LONG_CHUNK_PAGE).number)
            piece = piece[:window] + page + piece[window:]
        writes.append((offset.address, offset.encode(at) + piece))
    return writes


def commit_write(
    table: bytes, controller: Controller | None = None, *, what: str = "TABLE"
) -> tuple[int, bytes]:
    """The WRITE that commits: Upload Length, Upload CRC (zlib.crc32 of all the bytes) and
    Upload Commit in one packet; ``what`` names the Upload Commit value (TABLE: the staged
    bytes are a gait table; LIMITS: they are the robot's limits)."""
    ctl = controller or load()
    length = ctl.register("Upload Length")
    crc = ctl.register("Upload CRC")
    commit = ctl.register("Upload Commit")
    if not (length.end == crc.address and crc.end == commit.address):
        raise ControllerTableError(
            "the controller's description: Upload Length/CRC/Commit must be adjacent"
        )
    value = ctl.enums["Upload Commit"][what]
    data = length.encode(len(table)) + crc.encode(zlib.crc32(table)) + commit.encode(value)
    return length.address, data
