"""``.gait`` files: the table's bytes in FILE, its metadata in FILE.json beside it.

Both are written the one way outputs are (``snakebot.userfiles``): to temporary files in
the same directory, moved into place only when complete, so an error never leaves a
half-written file, and never through a symbolic link. The
sidecar records the table's CRC, so a sidecar that belongs to another table is noticed.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from snakebot.formats.gaittable.errors import GaitTableError
from snakebot.formats.gaittable.layout import MAX_TABLE_BYTES
from snakebot.formats.gaittable.table import GaitTable
from snakebot.userfiles import (
    FileTooLarge,
    OutputRefused,
    UnreadableInput,
    read_bounded,
    staged_output,
)

SIDECAR_FORMAT = "snakebot-gait-metadata"

MAX_SIDECAR_BYTES = 4 << 20
"""The largest metadata file read: the predicted paths of the longest table the
controller holds, sampled as the gait commands write them, take well under a megabyte."""


def sidecar_path(path: str | os.PathLike[str]) -> Path:
    """FILE.json for FILE."""
    path = Path(path)
    return path.with_name(path.name + ".json")


def write_gait(path: str | os.PathLike[str], table: GaitTable) -> None:
    """Write ``table`` to ``path`` (binary) and ``path``.json (metadata), atomically each."""
    path = Path(path)
    # What read_gait would refuse is not written in the first place.
    _check_metadata(table.metadata, "gait metadata", "give it the shape gait commands write")
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
    try:
        # The sidecar is moved into place first (the inner block ends first): if we die
        # between the two moves, the old binary and the new sidecar disagree on the CRC
        # and read_gait says so.
        with staged_output(path) as table_temp, staged_output(sidecar_path(path)) as side_temp:
            side_temp.write_bytes(text.encode())
            table_temp.write_bytes(table.encode())
    except OSError as exc:
        raise GaitTableError(
            f"cannot write gait table {path}: {exc.strerror or exc}; check the directory "
            "exists and is writable",
            "no_file",
        ) from exc
    except OutputRefused as exc:
        raise GaitTableError(f"cannot write gait table {path}: {exc}", "no_file") from None


def read_gait(path: str | os.PathLike[str]) -> GaitTable:
    """The table in ``path`` with the metadata from ``path``.json (empty if there is none);
    GaitTableError naming the problem (truncated, bad magic, CRC mismatch, ...)."""
    path = Path(path)
    try:
        data = read_bounded(path, MAX_TABLE_BYTES, "gait table")
    except UnreadableInput as exc:
        code = "too_big" if isinstance(exc, FileTooLarge) else "no_file"
        raise GaitTableError(str(exc), code) from exc
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
        raw = json.loads(
            read_bounded(sidecar, MAX_SIDECAR_BYTES, "gait metadata file"),
            parse_constant=_refuse_constant,
        )
        crc = raw["table"]["crc32"]
        metadata = raw["metadata"]
    except (OSError, ValueError, KeyError, TypeError, RecursionError, UnreadableInput) as exc:
        why = "nested too deeply" if isinstance(exc, RecursionError) else str(exc)
        raise GaitTableError(
            f"gait metadata {sidecar} is unreadable ({why}): delete it or write the gait again",
            "not_json",
        ) from exc
    if not isinstance(crc, int) or isinstance(crc, bool):
        raise GaitTableError(
            f"gait metadata {sidecar}: table.crc32 must be a number, not {_brief(crc)}: "
            "write the gait again, or delete the .json",
            "not_json",
        )
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
    _check_metadata(
        metadata, f"gait metadata {sidecar}", "write the gait again, or delete the .json"
    )
    return metadata


def _check_metadata(metadata: dict[str, Any], where: str, fix: str) -> None:
    """GaitTableError if a key snakebot reads holds the wrong kind of value."""
    for key, check in METADATA_SCHEMA.items():
        if key in metadata and not check(metadata[key]):
            raise GaitTableError(
                f"{where}: {key} is {_brief(metadata[key])}, not {check.__doc__}: {fix}",
                "not_json",
            )


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _brief(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _number(value: Any) -> bool:
    """a number"""
    return isinstance(value, int | float) and not isinstance(value, bool)


def _integer(value: Any) -> bool:
    """a whole number"""
    return isinstance(value, int) and not isinstance(value, bool)


def _text(value: Any) -> bool:
    """a string"""
    return isinstance(value, str)


def _flag(value: Any) -> bool:
    """true or false"""
    return isinstance(value, bool)


def _mapping(value: Any) -> bool:
    """an object"""
    return isinstance(value, dict)


def _numbers(value: Any) -> bool:
    """a list of numbers"""
    return isinstance(value, list) and all(_number(v) for v in value)


def _texts(value: Any) -> bool:
    """a list of strings"""
    return isinstance(value, list) and all(_text(v) for v in value)


def _motion(value: Any) -> bool:
    """an object with numbers dx, dy and dtheta"""
    return _mapping(value) and all(_number(value.get(k)) for k in ("dx", "dy", "dtheta"))


def _warnings(value: Any) -> bool:
    """a list of objects each with a string message"""
    return isinstance(value, list) and all(_mapping(w) and _text(w.get("message")) for w in value)


def _path(value: Any) -> bool:
    """an object of equally long number lists x, y and theta"""
    if not _mapping(value) or not all(_numbers(value.get(k)) for k in ("x", "y", "theta")):
        return False
    return len(value["x"]) == len(value["y"]) == len(value["theta"])


def _joints(value: Any) -> bool:
    """a list of joints with a name, servo_id, zero_tick and sign of 1 or -1"""
    return isinstance(value, list) and all(
        _mapping(j)
        and _text(j.get("name", ""))
        and _integer(j.get("servo_id"))
        and _integer(j.get("zero_tick"))
        and j.get("sign") in (1, -1)
        for j in value
    )


METADATA_SCHEMA: dict[str, Any] = {
    "gait": _text,
    "robot": _text,
    "robot_source": _text,
    "duration_s": _number,
    "frame_period_ms": _integer,
    "frames": _integer,
    "loop": _flag,
    "parameters": _mapping,
    "predicted": _motion,
    "table": _motion,
    "first_order": _motion,
    "second_order": _motion,
    "path": _path,
    "table_path": _path,
    "joints": _joints,
    "state_names": _texts,
    "warnings": _warnings,
    "frame": _text,
    "length_unit": _text,
    "length_legend": _text,
    "final_q": _numbers,
    "moved_q": _numbers,
}
"""What the metadata keys that snakebot reads must hold (each check's docstring says it in
words, for the error message). Other keys are kept as they are, for the user."""


def save_table(path: str | os.PathLike[str], table: GaitTable) -> dict[str, Any]:
    """Write ``table`` (and its metadata file) and say where: ``file`` and ``metadata_file``."""
    write_gait(path, table)
    return {"file": str(path), "metadata_file": str(sidecar_path(path))}


HIDDEN_METADATA = ("path", "table_path", "joints")
"""Metadata a table's summary leaves out: where it was written, and what the bytes say."""


def describe_table(path: str | os.PathLike[str], table: GaitTable) -> dict[str, Any]:
    """A table file's summary: its metadata (the gait, its predictions), and over it what
    the table's bytes say (which wins over anything the metadata file claims). The header
    CRC is stored in the table over the rest of it; the file CRC-32, of all its bytes, is
    what the controller calls its Table CRC."""
    computed = {
        "file": str(path),
        "bytes": table.size,
        "header_crc": f"0x{table.crc:08X}",
        "file_crc32": f"0x{table.image_crc:08X}",
        "joint_ids": list(table.joint_ids),
        "limits": [list(x) for x in table.limits],
        "frames": table.frame_count,
        "frame_period_ms": table.frame_period_ms,
        "loop": table.loop,
        "duration_s": table.duration_ms / 1000.0,
    }
    shown = {k: v for k, v in table.metadata.items() if k not in HIDDEN_METADATA}
    return {**shown, **computed}
