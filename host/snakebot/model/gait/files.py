"""A gait written out as a gait table (``FILE`` and its metadata ``FILE.json``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from snakebot.formats.gaittable import GaitTable, save_table
from snakebot.model.gait.common import Gait


def save_gait(gait: Gait, path: Path) -> tuple[GaitTable, dict[str, Any]]:
    """Write ``gait``'s table to ``path``: the table, and the gait's summary with where
    it was written (``file``, ``metadata_file``) and its size (``bytes``)."""
    table = gait.gait_table()
    summary = {**save_table(path, table), "bytes": table.size, **gait.summary()}
    return table, summary
