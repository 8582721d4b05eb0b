"""The WRITEs that upload a gait table to the controller (protocol/controller.md,
"Uploading a gait table"), as (address, data) pairs any Protocol 1.0 client can send.

The transport (retries, timeouts, progress) belongs to the upload command; this module
only knows the layout, so the addresses come from the controller's description and nowhere else.
"""

from __future__ import annotations

import zlib

from snakebot.controller.table import Controller, ControllerTableError, load


def chunk_writes(
    table: bytes, chunk: int | None = None, controller: Controller | None = None
) -> list[tuple[int, bytes]]:
    """One WRITE per chunk: at Upload Offset, the chunk's offset (2 bytes) then its bytes.
    The first chunk is at offset 0 (which starts an upload on the controller)."""
    ctl = controller or load()
    window = ctl.register("Upload Data").size
    size = window if chunk is None else chunk
    if not 1 <= size <= window:
        raise ControllerTableError(f"upload chunk must be 1..{window} bytes, got {size}")
    capacity = ctl.limits["max_table_bytes"]
    if not 1 <= len(table) <= capacity:
        raise ControllerTableError(
            f"a table of {len(table)} bytes cannot be uploaded: the controller holds 1.."
            f"{capacity} bytes; use fewer frames"
        )
    offset = ctl.register("Upload Offset")
    return [
        (offset.address, at.to_bytes(offset.size, "little") + table[at : at + size])
        for at in range(0, len(table), size)
    ]


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
