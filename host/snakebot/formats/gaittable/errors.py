"""The gait-table error, carrying the validation code the firmware would report."""

from __future__ import annotations

from snakebot.errors import InputError

# Validation codes shared with gt_validate() in firmware/core/gt_table.h, in check order
# (protocol/gait_table.md, "Validation order").
CODES: dict[str, int] = {
    "ok": 0,
    "truncated": 1,
    "bad_magic": 2,
    "bad_version": 3,
    "bad_joint_count": 4,
    "bad_flags": 5,
    "bad_period": 6,
    "bad_frame_count": 7,
    "too_big": 8,
    "trailing_bytes": 9,
    "crc_mismatch": 10,
    "bad_joint_id": 11,
    "bad_limits": 12,
    "frame_out_of_limits": 13,
}


class GaitTableError(InputError):
    """A gait table that cannot be built, stored, read or played.

    ``reason`` names the problem ("crc_mismatch", "too_big", ... or, for problems only the
    host can have, "bad_frames", "not_json", "no_file", "sidecar_mismatch"); ``code`` is
    the firmware's validation code for the same problem, or None.
    """

    def __init__(self, message: str, reason: str) -> None:
        super().__init__(message)
        self.reason = reason
        self.code: int | None = CODES.get(reason)
