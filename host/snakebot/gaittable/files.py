"""``.gait`` files: the table's bytes in FILE, its metadata in FILE.json beside it.

Both are written to temporary files in the same directory first and moved into place
with ``os.replace`` only when complete, so an error never leaves a half-written file. The
sidecar records the table's CRC, so a sidecar that belongs to another table is noticed.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any

from snakebot.gaittable.errors import GaitTableError
from snakebot.gaittable.table import GaitTable

SIDECAR_FORMAT = "snakebot-gait-metadata"


def sidecar_path(path: str | os.PathLike[str]) -> Path:
    """FILE.json for FILE."""
    path = Path(path)
    return path.with_name(path.name + ".json")


def write_gait(path: str | os.PathLike[str], table: GaitTable) -> None:
    """Write ``table`` to ``path`` (binary) and ``path``.json (metadata), atomically each."""
    path = Path(path)
    sidecar = {
        "format": SIDECAR_FORMAT,
        "table": {
            "crc32": table.image_crc,
            "size": table.size,
            "joint_ids": list(table.joint_ids),
            "frame_period_ms": table.frame_period_ms,
            "frame_count": table.frame_count,
            "loop": table.loop,
        },
        "metadata": table.metadata,
    }
    try:
        text = json.dumps(sidecar, indent=2, sort_keys=True, allow_nan=False) + "\n"
    except (TypeError, ValueError) as exc:
        raise GaitTableError(
            f"gait metadata is not JSON-able ({exc}): keep it to dicts, lists, strings, "
            "finite numbers and booleans (convert numpy values with float()/int()/.tolist())",
            "not_json",
        ) from exc
    staged: list[tuple[Path, Path]] = []
    try:
        for target, data in ((sidecar_path(path), text.encode()), (path, table.encode())):
            staged.append((_stage(target, data), target))
        # The sidecar goes first: if we die between the two moves, the old binary and the
        # new sidecar disagree on the CRC and read_gait says so.
        for temp, target in staged:
            os.replace(temp, target)
    except OSError as exc:
        raise GaitTableError(
            f"cannot write gait table {path}: {exc.strerror or exc}; check the directory "
            "exists and is writable",
            "no_file",
        ) from exc
    finally:
        for temp, _ in staged:
            if temp.exists():
                temp.unlink()


def _stage(target: Path, data: bytes) -> Path:
    fd, name = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        Path(name).unlink(missing_ok=True)
        raise
    return Path(name)


def read_gait(path: str | os.PathLike[str]) -> GaitTable:
    """The table in ``path`` with the metadata from ``path``.json (empty if there is none);
    GaitTableError naming the problem (truncated, bad magic, CRC mismatch, ...)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise GaitTableError(
            f"cannot read gait table {path}: {exc.strerror or exc}; check the path "
            "(tables are written by `snakebot gait ...`)",
            "no_file",
        ) from exc
    table = GaitTable.decode(data)
    metadata = _read_metadata(sidecar_path(path), table)
    return GaitTable.decode(data, metadata) if metadata else table


def _read_metadata(sidecar: Path, table: GaitTable) -> dict[str, Any]:
    if not sidecar.exists():
        return {}
    try:
        raw = json.loads(sidecar.read_text())
        crc = raw["table"]["crc32"]
        metadata = raw["metadata"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise GaitTableError(
            f"gait metadata {sidecar} is unreadable ({exc}): delete it or write the gait again",
            "not_json",
        ) from exc
    if crc != table.image_crc:
        raise GaitTableError(
            f"gait metadata {sidecar} belongs to another table (CRC 0x{crc:08x}, the table is "
            f"0x{table.image_crc:08x}): write the gait again, or delete the stale .json",
            "sidecar_mismatch",
        )
    if not isinstance(metadata, dict):
        raise GaitTableError(
            f"gait metadata in {sidecar} is not an object: write the gait again", "not_json"
        )
    return metadata
