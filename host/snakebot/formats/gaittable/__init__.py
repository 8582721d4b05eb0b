"""Gait tables: the exact bytes the controller stores and plays (protocol/gait_table.md).

from snakebot.formats.gaittable import GaitTable, write_gait, read_gait, GaitTableError
table = GaitTable(joint_ids=(1, 2), frame_period_ms=20, loop=True,
                  limits=((200, 824), (200, 824)), frames=ticks, metadata={...})
write_gait("walk.gait", table)      # walk.gait + walk.gait.json

May import: as the ``formats`` layer (``facts`` and the package root).
"""

from __future__ import annotations

from snakebot.formats.gaittable.errors import CODES, GaitTableError
from snakebot.formats.gaittable.files import read_gait, sidecar_path, write_gait
from snakebot.formats.gaittable.layout import (
    HEADER_SIZE,
    JOINT_SIZE,
    MAGIC,
    MAX_JOINTS,
    MAX_TABLE_BYTES,
    VERSION,
    max_frames,
    table_crc,
    table_size,
)
from snakebot.formats.gaittable.table import GaitTable

__all__ = [
    "CODES",
    "HEADER_SIZE",
    "JOINT_SIZE",
    "MAGIC",
    "MAX_JOINTS",
    "MAX_TABLE_BYTES",
    "VERSION",
    "GaitTable",
    "GaitTableError",
    "max_frames",
    "read_gait",
    "sidecar_path",
    "table_crc",
    "table_size",
    "write_gait",
]
