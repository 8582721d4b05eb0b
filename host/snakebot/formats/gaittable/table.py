"""``GaitTable``: the frames a controller plays, with the header it checks them against."""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from snakebot.formats.gaittable import layout
from snakebot.formats.gaittable.errors import GaitTableError


@dataclass(frozen=True, eq=False)
class GaitTable:
    """A gait table: ``frames[k, j]`` is joint ``j``'s goal in AX-12 ticks at
    ``k * frame_period_ms``. The constructor checks everything the controller will check
    (GaitTableError otherwise); ``frames`` is stored as a read-only uint16 array."""

    joint_ids: tuple[int, ...]
    frame_period_ms: int
    loop: bool
    limits: tuple[tuple[int, int], ...]  # per joint (min_tick, max_tick)
    frames: np.ndarray  # (frame_count, joints) uint16
    metadata: dict[str, Any] = field(default_factory=dict)  # JSON-able, kept in FILE.json

    def __post_init__(self) -> None:
        ids = tuple(int(i) for i in self.joint_ids)
        limits = tuple((int(lo), int(hi)) for lo, hi in self.limits)
        object.__setattr__(self, "joint_ids", ids)
        object.__setattr__(self, "limits", limits)
        object.__setattr__(self, "loop", bool(self.loop))
        object.__setattr__(self, "metadata", dict(self.metadata))
        fix = "fix the robot description"
        if not 1 <= len(ids) <= layout.MAX_JOINTS:
            raise GaitTableError(
                f"a gait table needs 1..{layout.MAX_JOINTS} joints, got {len(ids)}: {fix}",
                "bad_joint_count",
            )
        for j, sid in enumerate(ids):
            if not 0 <= sid <= layout.MAX_ID or sid in ids[:j]:
                why = "outside 0..253" if not 0 <= sid <= layout.MAX_ID else "given twice"
                raise GaitTableError(f"servo ID {sid} is {why}: {fix}", "bad_joint_id")
        if len(limits) != len(ids):
            raise GaitTableError(
                f"{len(limits)} limit pairs for {len(ids)} joints: give one (min, max) per joint",
                "bad_limits",
            )
        for j, (lo, hi) in enumerate(limits):
            if not 0 <= lo <= hi <= layout.MAX_TICK:
                raise GaitTableError(
                    f"joint {j} (ID {ids[j]}) has limits {lo}..{hi}: need "
                    f"0 <= min <= max <= {layout.MAX_TICK}; {fix}",
                    "bad_limits",
                )
        if not 1 <= int(self.frame_period_ms) <= layout.MAX_PERIOD_MS:
            raise GaitTableError(
                f"frame period {self.frame_period_ms} ms is outside 1..{layout.MAX_PERIOD_MS}",
                "bad_period",
            )
        object.__setattr__(self, "frame_period_ms", int(self.frame_period_ms))
        frames = _as_ticks(self.frames, len(ids))
        if len(frames) > layout.MAX_FRAME_COUNT or (
            layout.table_size(len(ids), len(frames)) > layout.MAX_TABLE_BYTES
        ):
            raise GaitTableError(layout.too_big_message(len(ids), len(frames)), "too_big")
        layout.check_frames(frames, limits, ids)
        frames.flags.writeable = False
        object.__setattr__(self, "frames", frames)

    @property
    def joint_count(self) -> int:
        return len(self.joint_ids)

    @property
    def frame_count(self) -> int:
        return len(self.frames)

    @property
    def duration_ms(self) -> int:
        """One pass: a loop lasts F periods (it wraps back to frame 0), a single play F - 1."""
        return self.frame_period_ms * (self.frame_count if self.loop else self.frame_count - 1)

    @property
    def size(self) -> int:
        """Bytes the controller stores."""
        return layout.table_size(self.joint_count, self.frame_count)

    def encode(self) -> bytes:
        """The exact bytes the controller stores (protocol/gait_table.md)."""
        return layout.encode(
            self.joint_ids, self.frame_period_ms, self.loop, self.limits, self.frames
        )

    @property
    def crc(self) -> int:
        """The table CRC stored in the header (CRC field left out)."""
        return int.from_bytes(self.encode()[layout.CRC_OFFSET : layout.HEADER_SIZE], "little")

    @property
    def image_crc(self) -> int:
        """CRC-32 of all the bytes (what the upload commit and Table CRC register carry)."""
        return zlib.crc32(self.encode())

    @classmethod
    def decode(cls, data: bytes, metadata: dict[str, Any] | None = None) -> GaitTable:
        """The table stored in ``data``; GaitTableError naming the first problem found, in
        the order the controller checks."""
        ids, period, loop, limits, frames = layout.decode(data)
        return cls(ids, period, loop, limits, frames, metadata or {})

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, GaitTable):
            return NotImplemented
        return self.encode() == other.encode() and self.metadata == other.metadata

    __hash__ = None  # type: ignore[assignment]  # mutable metadata


def _as_ticks(frames: object, joints: int) -> np.ndarray:
    array = np.asarray(frames)
    if array.ndim != 2 or array.shape[1] != joints:
        raise GaitTableError(
            f"frames must be a (frame_count, {joints}) array, one column per joint; got "
            f"shape {array.shape}",
            "bad_frames",
        )
    if array.shape[0] == 0:
        raise GaitTableError("a gait table needs at least one frame", "bad_frame_count")
    if not (np.issubdtype(array.dtype, np.integer) or np.issubdtype(array.dtype, np.floating)):
        raise GaitTableError(
            f"frames must be numbers (ticks), got dtype {array.dtype}", "bad_frames"
        )
    if np.issubdtype(array.dtype, np.floating) and not (
        np.isfinite(array).all() and (array == np.round(array)).all()
    ):
        raise GaitTableError(
            "frames must be whole ticks: round the angles to ticks first "
            "(Robot.angles_to_ticks does)",
            "bad_frames",
        )
    if array.size and (array.min() < 0 or array.max() > layout.MAX_TICK):
        raise GaitTableError(
            f"frames must be ticks in 0..{layout.MAX_TICK}, got {array.min()}..{array.max()}",
            "frame_out_of_limits",
        )
    return np.array(array, dtype=np.uint16)
