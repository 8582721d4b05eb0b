"""Build a program from a spec: a TOML or JSON list of segments in SI units (rad, rad/s,
seconds), for the joints of a robot description.

    robot = "snake5"          # or --robot; the program drives its joints in order
    period_ms = 20            # one program step
    table = "walk.gait"       # optional: the frames TABLE segments play (same period)

    [[segment]]
    kind = "periodic"         # phi_k = rate_k t + sin_k sin(omega t) + cos_k cos(omega t)
    omega = 3.14
    rate = [0.05, 0.0, 0.0, 0.0, -0.05]
    sin = [0.3, 0.3, 0.3, 0.3, 0.3]
    duration = 2.0

    [[segment]]
    kind = "serpenoid"        # phi_k = amplitude sin(omega t + k delta) + offset
    amplitude = 0.5
    omega = 3.14
    delta = 1.05
    duration = 4.0

    [[segment]]
    kind = "table"            # frames first..first+count-1, repetitions times
    repetitions = 2
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from snakebot.errors import quoted
from snakebot.formats.gaittable import GaitTableError, read_gait
from snakebot.formats.nesting import too_deep
from snakebot.formats.program.errors import ProgramError
from snakebot.formats.program.layout import (
    Block,
    JointRecord,
    PeriodicSegment,
    Program,
    Segment,
    SerpenoidSegment,
    TableSegment,
    check,
)
from snakebot.model.robots import Robot, load_robot
from snakebot.model.robots.model import RobotError
from snakebot.userfiles import UnreadableInput, read_bounded

MRAD = 1000.0
MAX_SPEC_BYTES = 1 << 20
KINDS = ("table", "serpenoid", "periodic")
FIELDS = {
    "table": {"kind", "first", "count", "repetitions"},
    "serpenoid": {"kind", "amplitude", "omega", "delta", "offset", "duration"},
    "periodic": {"kind", "omega", "rate", "sin", "cos", "duration"},
}


def load_spec(path: str | Path) -> dict[str, Any]:
    """The spec in ``path`` (TOML, or JSON when it ends in .json) as a dictionary."""
    path = Path(path)
    try:
        text = read_bounded(path, MAX_SPEC_BYTES, "program spec").decode("utf-8")
    except (UnreadableInput, UnicodeDecodeError) as exc:
        raise ProgramError(f"{path}: {exc}") from exc
    except OSError as exc:
        raise ProgramError(
            f"cannot read program spec {path}: {exc.strerror or exc}; check the path"
        ) from exc
    deep = too_deep(text, comments=path.suffix != ".json")
    if deep is not None:
        raise ProgramError(f"{path} {deep}")
    try:
        data = json.loads(text) if path.suffix == ".json" else tomllib.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        kind = "JSON" if path.suffix == ".json" else "TOML"
        raise ProgramError(f"{path} is not valid {kind} ({exc}): fix the spec") from exc
    if not isinstance(data, dict):
        raise ProgramError(f"{path}: the spec must be a table of keys, not {type(data).__name__}")
    return data


def joints_of(robot: Robot) -> tuple[JointRecord, ...]:
    """The program's joint records for ``robot``: IDs, zero ticks, directions, limits."""
    return tuple(
        JointRecord(j.servo_id, j.zero_tick, j.tick_range[0], j.tick_range[1], j.sign < 0)
        for j in robot.joints
    )


class _Reader:
    """Typed access to one segment's keys, failing with the segment and key named."""

    def __init__(self, index: int, entry: dict[str, Any]) -> None:
        self.where = f"segment {index + 1}"
        self.entry = entry

    def fail(self, message: str) -> ProgramError:
        return ProgramError(f"{self.where}: {message}")

    def number(self, key: str, default: float | None = None) -> float:
        value = self.entry.get(key, default)
        if value is None:
            raise self.fail(f"`{key}` is missing: give it a number")
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise self.fail(f"`{key}` must be a finite number, got {quoted(value)}")
        return float(value)

    def integer(self, key: str, default: int | None = None) -> int:
        value = self.number(key, default)
        if value != int(value) or value < 0:
            raise self.fail(f"`{key}` must be a whole number >= 0, got {value:g}")
        return int(value)

    def numbers(self, key: str, count: int) -> list[float]:
        value = self.entry.get(key, [0.0] * count)
        if not isinstance(value, list) or len(value) != count:
            raise self.fail(
                f"`{key}` must list one number per joint ({count}), got {quoted(value)}"
            )
        for v in value:
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise self.fail(f"`{key}` must list finite numbers, got {quoted(v)}")
        return [float(v) for v in value]


def _int16(reader: _Reader, key: str, value: float, scale: float = MRAD) -> int:
    scaled = round(value * scale)
    if not -32768 <= scaled <= 32767:
        raise reader.fail(f"`{key}` = {value:g} is beyond what a program can hold")
    return scaled


def _steps(reader: _Reader, period_ms: int) -> int:
    seconds = reader.number("duration")
    steps = round(seconds * 1000.0 / period_ms)
    if not 1 <= steps <= 0xFFFF:
        raise reader.fail(
            f"`duration` = {seconds:g} s is {steps} steps of {period_ms} ms; a segment has "
            "1..65535: split it or change period_ms"
        )
    return steps


def _segment(
    reader: _Reader, period_ms: int, n_joints: int, n_frames: int, blocks: list[Block]
) -> Segment:
    kind = reader.entry.get("kind")
    if kind not in KINDS:
        raise reader.fail(f"`kind` must be one of {', '.join(KINDS)}, got {quoted(kind)}")
    unknown = sorted(set(reader.entry) - FIELDS[kind])
    if unknown:
        raise reader.fail(f"unknown key(s) {', '.join(unknown)} for a {kind} segment")
    if kind == "table":
        if n_frames == 0:
            raise reader.fail("a table segment needs frames: set `table = FILE.gait` in the spec")
        first = reader.integer("first", 0)
        count = reader.integer("count", max(n_frames - first, 1))
        return TableSegment(first, count, reader.integer("repetitions", 1))
    omega = _int16(reader, "omega", reader.number("omega"))
    if kind == "serpenoid":
        amplitude = _int16(reader, "amplitude", reader.number("amplitude"))
        if amplitude < 0:
            raise reader.fail("`amplitude` must be >= 0 (a negative one is a phase shift of pi)")
        delta = _int16(reader, "delta", reader.number("delta"))
        offset = _int16(reader, "offset", reader.number("offset", 0.0))
        return SerpenoidSegment(amplitude, omega, delta, offset, _steps(reader, period_ms))
    rows = zip(
        *(reader.numbers(key, n_joints) for key in ("rate", "sin", "cos")),
        strict=True,
    )
    block = tuple(tuple(_int16(reader, "rate/sin/cos", v) for v in row) for row in rows)
    if block not in blocks:
        blocks.append(block)  # type: ignore[arg-type]
    return PeriodicSegment(blocks.index(block), omega, _steps(reader, period_ms))  # type: ignore[arg-type]


def build_program(
    spec: dict[str, Any], robot: str | None = None, base: Path = Path(".")
) -> Program:
    """The program a spec describes (``robot`` overrides the spec's), checked by the
    controller's own code: ProgramError naming the segment and the fix otherwise."""
    name = robot or spec.get("robot")
    if not isinstance(name, str):
        raise ProgramError(
            'the spec names no robot: add `robot = "snake5"` to it or name the robot'
        ).about("robot")
    try:
        model = load_robot(name)
    except RobotError as exc:
        raise ProgramError(str(exc)) from exc
    joints = joints_of(model)
    period = spec.get("period_ms", 20)
    if isinstance(period, bool) or not isinstance(period, int) or not 1 <= period <= 1000:
        raise ProgramError(
            f"`period_ms` must be a whole number of ms in 1..1000, got {quoted(period)}"
        )
    frames: tuple[tuple[int, ...], ...] = ()
    if "table" in spec:
        frames = _frames(spec["table"], base, model, period)
    entries = spec.get("segment")
    if not isinstance(entries, list) or not entries:
        raise ProgramError("the spec has no segments: add [[segment]] entries")
    blocks: list[Block] = []
    segments = []
    for index, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise ProgramError(f"segment {index + 1} must be a table of keys")
        reader = _Reader(index, entry)
        segments.append(_segment(reader, period, len(joints), len(frames), blocks))
    program = Program(period, joints, tuple(segments), tuple(blocks), frames)
    check(program.encode())
    return program


def _frames(value: Any, base: Path, robot: Robot, period: int) -> tuple[tuple[int, ...], ...]:
    if not isinstance(value, str):
        raise ProgramError(f"`table` must name a .gait file, got {quoted(value)}")
    path = base / value
    try:
        table = read_gait(path)
    except GaitTableError as exc:
        raise ProgramError(f"table {path}: {exc}") from exc
    if table.joint_ids != robot.servo_ids:
        raise ProgramError(
            f"table {path} drives servos {list(table.joint_ids)}, the robot "
            f"{list(robot.servo_ids)}: generate the table for the same robot"
        )
    if table.frame_period_ms != period:
        raise ProgramError(
            f"table {path} has a frame every {table.frame_period_ms} ms, the program a step "
            f"every {period} ms: set period_ms = {table.frame_period_ms} or regenerate the table"
        )
    return tuple(tuple(int(v) for v in row) for row in table.frames)
