"""A controller program in SI units, as `snakebot program show` prints it: its size,
CRC-32, timing, joints, and each segment's parameters (mrad to rad, steps to seconds)."""

from __future__ import annotations

import os
import zlib
from typing import Any

from snakebot.formats.program.layout import PeriodicSegment, Program, SerpenoidSegment, TableSegment

MRAD = 1000.0


def describe_program(prog: Program, path: str | os.PathLike[str]) -> dict[str, Any]:
    """The program as plain data (``path`` is where it was read or written)."""
    data = prog.encode()
    return {
        "file": str(path),
        "bytes": len(data),
        "crc": f"0x{zlib.crc32(data):08x}",
        "period_ms": prog.period_ms,
        "steps": prog.total_steps,
        "duration_s": prog.duration_s,
        "joints": [
            {"id": j.servo_id, "zero": j.zero, "min": j.low, "max": j.high, "reverse": j.reverse}
            for j in prog.joints
        ],
        "frames": len(prog.frames),
        "segments": [_segment(prog, s) for s in prog.segments],
    }


def _segment(prog: Program, seg: object) -> dict[str, Any]:
    seconds = getattr(seg, "steps", 0) * prog.period_ms / 1000.0
    if isinstance(seg, TableSegment):
        return {
            "kind": "table",
            "first": seg.first,
            "count": seg.count,
            "repetitions": seg.repetitions,
            "duration_s": seconds,
        }
    if isinstance(seg, SerpenoidSegment):
        return {
            "kind": "serpenoid",
            "amplitude": seg.amp_mrad / MRAD,
            "omega": seg.omega_mrad_s / MRAD,
            "delta": seg.delta_mrad / MRAD,
            "offset": seg.phi0_mrad / MRAD,
            "duration_s": seconds,
        }
    assert isinstance(seg, PeriodicSegment)
    rows = prog.blocks[seg.block]
    return {
        "kind": "periodic",
        "omega": seg.omega_mrad_s / MRAD,
        "rate": [r[0] / MRAD for r in rows],
        "sin": [r[1] / MRAD for r in rows],
        "cos": [r[2] / MRAD for r in rows],
        "duration_s": seconds,
    }
