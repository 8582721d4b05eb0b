"""Reading robot descriptions from TOML, with errors that name the key and its line.

A robot file has the top-level keys ``name``, ``kind`` ("snake", "trident" or "car") and
``description``, and the tables ``[geometry]``, ``[friction]``, ``[servo]``,
``[limits]``, ``[[joints]]`` and ``[physics]``. What each key means, its unit and its
range are in :mod:`snakebot.model.robots.schema` (``snakebot robot new`` writes them as
comments); the built-in files beside this module are complete examples.
"""

from __future__ import annotations

import difflib
import functools
import math
import re
import sys
from importlib import resources
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # the same parser as a package (a dependency on Python 3.10 only)
    import tomli as tomllib

from snakebot.errors import quoted
from snakebot.formats.nesting import too_deep
from snakebot.model.robots.model import (
    DEFAULT_FRICTION,
    PHYSICS_DEFAULTS,
    SERVO_MAX_RPM,
    SPEED_LIMITS,
    TICK_MAX,
    TICK_MIN,
    TORQUE_LIMIT,
    Friction,
    Joint,
    Physics,
    Robot,
    RobotError,
    joint_name,
)
from snakebot.model.robots.schema import MAX_LINKS, MAX_SERVO_ID, schema
from snakebot.userfiles import UnreadableInput, read_bounded

BUILTIN_ROBOTS = ("snake3", "trident", "snake5", "car")
MAX_FILE_BYTES = 1 << 20  # a robot description is a few hundred bytes; this is no robot
MAX_LIMIT_DEG = 360.0  # joint limits beyond a full turn are typing errors, whatever the servo

_NEW_FRICTION = (
    "friction is now given in physical units, the same for both worlds: [friction] "
    "lateral (wheel-floor Coulomb coefficient), rolling (rolling resistance coefficient) "
    "and axle_nm (axle friction torque); see docs/models.md"
)
REMOVED_KEYS: dict[tuple[str, ...], str] = {
    ("friction", "c_n"): _NEW_FRICTION,
    ("friction", "c_t"): _NEW_FRICTION,
    ("physics", "mu"): "moved: the wheel-floor coefficient is [friction] lateral",
    ("physics", "rolling_damping"): "moved: the wheels' axle friction is [friction] axle_nm "
    "(a torque in N m) and their rolling resistance [friction] rolling",
}
"""Keys of earlier robot files, refused with what replaces them."""

SCHEMA: dict[str, Any] = schema()
"""The keys a robot file may have: None for a value, a set for a table's keys, a list
holding that set for an array of tables. A key not here is refused with a "did you mean"
(a misspelt optional key would otherwise be silently ignored)."""

_PERCENT = re.compile(r"^\s*([0-9]+(?:\.[0-9]*)?|\.[0-9]+)\s*%\s*$")
_ARRAY_HEADER = re.compile(r"^\s*\[\[\s*([A-Za-z0-9_.\-]+)\s*\]\]")
_TABLE_HEADER = re.compile(r"^\s*\[\s*([A-Za-z0-9_.\-]+)\s*\]")
_KEY_LINE = re.compile(r'^\s*"?([A-Za-z0-9_\-]+)"?\s*=')


def _key_lines(text: str) -> dict[tuple[str, ...], int]:
    """Map key paths such as ("joints", "2", "sign") or ("geometry",) to 1-based lines."""
    lines: dict[tuple[str, ...], int] = {}
    table: tuple[str, ...] = ()
    counts: dict[str, int] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        if m := _ARRAY_HEADER.match(line):
            name = m.group(1)
            index = counts.get(name, 0)
            counts[name] = index + 1
            table = (name, str(index))
            lines.setdefault(table, number)
            lines.setdefault((name,), number)
        elif m := _TABLE_HEADER.match(line):
            table = tuple(m.group(1).split("."))
            lines.setdefault(table, number)
        elif m := _KEY_LINE.match(line):
            lines.setdefault((*table, m.group(1)), number)
    return lines


class _Reader:
    """Typed access to the parsed TOML that raises ``RobotError`` naming key and line."""

    def __init__(self, data: dict[str, Any], text: str, source: str) -> None:
        self.data = data
        self.lines = _key_lines(text)
        self.source = source

    def where(self, path: tuple[str, ...]) -> str:
        for n in range(len(path), 0, -1):
            if path[:n] in self.lines:
                return f"{self.source}, line {self.lines[path[:n]]}"
        return self.source

    def fail(self, path: tuple[str, ...], problem: str) -> RobotError:
        key = ".".join(p if not p.isdigit() else f"[{p}]" for p in path).replace(".[", "[")
        return RobotError(f"{self.where(path)}: key '{key}' {problem}")

    def get(self, path: tuple[str, ...], kind: type | tuple[type, ...], default: Any = ...) -> Any:
        node: Any = self.data
        for n, part in enumerate(path):
            if isinstance(node, list) and part.isdigit() and int(part) < len(node):
                node = node[int(part)]
            elif isinstance(node, dict) and part in node:
                node = node[part]
            elif n and not isinstance(node, dict | list):
                raise self.fail(path[:n], f"must be a table, not {_brief(node)}")
            elif default is not ...:
                return default
            else:
                raise self.fail(path, "is missing: add it (see the built-in robot files)")
        kinds = kind if isinstance(kind, tuple) else (kind,)
        if float in kinds and isinstance(node, int) and not isinstance(node, bool):
            if abs(node) > 1e300:  # float() of a longer integer overflows
                raise self.fail(path, f"must be a reasonable number, not {_brief(node)}")
            node = float(node)
        if isinstance(node, bool) and bool not in kinds or not isinstance(node, kinds):
            names = " or ".join(k.__name__ for k in kinds).replace("str", "a string")
            raise self.fail(path, f"must be {names}, not {_brief(node)}")
        return node

    def number(
        self,
        path: tuple[str, ...],
        low: float | None = None,
        default: Any = ...,
        strictly: bool = False,
        high: float | None = None,
        why_high: str = "",
    ) -> float:
        value = self.get(path, float, default)
        if not math.isfinite(value):
            raise self.fail(path, f"must be a finite number, not {value}")
        if low is not None and (value < low or (strictly and value == low)):
            relation = ">" if strictly else ">="
            raise self.fail(path, f"must be {relation} {low}, not {value}")
        if high is not None and value > high:
            raise self.fail(path, f"must be at most {high:g}{why_high}, not {value:g}")
        return value

    def check_keys(self, schema: dict[str, Any], node: Any, path: tuple[str, ...] = ()) -> None:
        """Refuse keys the schema does not know (with the closest known one) and tables
        or arrays of tables given as something else."""
        for key, value in node.items():
            here = (*path, key)
            if key not in schema:
                close = difflib.get_close_matches(key, list(schema), n=1)
                hint = (
                    f"did you mean '{close[0]}'?" if close else "known keys: " + ", ".join(schema)
                )
                raise self.fail(here, f"is not a robot description key: {hint}")
            expected = schema[key]
            if isinstance(expected, set):
                if not isinstance(value, dict):
                    raise self.fail(here, f"must be a table ([{key}]), not {_brief(value)}")
                self.check_keys(dict.fromkeys(expected), value, here)
            elif isinstance(expected, list):
                if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
                    raise self.fail(here, f"must be tables ([[{key}]]), not {_brief(value)}")
                for i, item in enumerate(value):
                    self.check_keys(dict.fromkeys(expected[0]), item, (*here, str(i)))

    def integer(self, path: tuple[str, ...], low: int, high: int) -> int:
        value = self.get(path, int)
        if not low <= value <= high:
            raise self.fail(path, f"must be between {low} and {high}, not {value}")
        return value


def _joint(reader: _Reader, index: int) -> Joint:
    base = ("joints", str(index))
    sign = reader.get((*base, "sign"), int)
    if sign not in (1, -1):
        raise reader.fail((*base, "sign"), f"must be 1 or -1, not {sign}")
    low = reader.number((*base, "min_deg"), -MAX_LIMIT_DEG, high=MAX_LIMIT_DEG)
    high = reader.number((*base, "max_deg"), -MAX_LIMIT_DEG, high=MAX_LIMIT_DEG)
    if low >= high:
        raise reader.fail((*base, "max_deg"), f"must be greater than min_deg ({low}), not {high}")
    joint = Joint(
        name=reader.get((*base, "name"), str, joint_name(index)),
        servo_id=reader.integer((*base, "servo_id"), 0, MAX_SERVO_ID),
        zero_tick=reader.integer((*base, "zero_tick"), TICK_MIN, TICK_MAX),
        sign=sign,
        min_rad=math.radians(low),
        max_rad=math.radians(high),
    )
    for key, tick in (
        ("min_deg", joint.angle_to_tick(joint.min_rad)),
        ("max_deg", joint.angle_to_tick(joint.max_rad)),
    ):
        if not TICK_MIN <= tick <= TICK_MAX:
            raise reader.fail(
                (*base, key),
                f"maps to tick {tick}, outside the servo's 0-1023: narrow the limit or move "
                "zero_tick",
            )
    return joint


def _torque_limit(reader: _Reader) -> int | None:
    """``[limits] torque`` as a raw Torque Limit (None when not given): a percentage of
    stall torque, written "60%" or 60, above 0 (a servo held to 0 cannot move)."""
    path = ("limits", "torque")
    value = reader.get(path, (str, float), None)
    if value is None:
        return None
    unit = TORQUE_LIMIT.scale.unit if TORQUE_LIMIT.scale is not None else "%"
    if isinstance(value, str):
        match = _PERCENT.match(value)
        if match is None:
            raise reader.fail(path, f'must be a percentage such as "60%", not {_brief(value)}')
        value = float(match.group(1))
    if not math.isfinite(value):
        raise reader.fail(path, f"must be a finite percentage, not {value}")
    raw = TORQUE_LIMIT.from_units(value)
    low, high = TORQUE_LIMIT.value_range()
    top = TORQUE_LIMIT.to_units(high)
    if raw <= low or raw > high:
        raise reader.fail(path, f"must be above 0 and at most {top:g}{unit}, not {value:g}%")
    return raw


def _physics(reader: _Reader) -> Physics | None:
    if "physics" not in reader.data:
        return None
    values = {
        key: reader.number(("physics", key), 0.0, default, strictly=True)
        for key, default in PHYSICS_DEFAULTS.items()
    }
    return Physics(unit_m=reader.number(("physics", "unit_m"), 0.0, strictly=True), **values)


def _friction(reader: _Reader) -> Friction:
    d = DEFAULT_FRICTION
    return Friction(
        lateral=reader.number(("friction", "lateral"), 0.0, d.lateral, strictly=True),
        rolling=reader.number(("friction", "rolling"), 0.0, d.rolling),
        axle_nm=reader.number(("friction", "axle_nm"), 0.0, d.axle_nm),
    )


def _refuse_removed(reader: _Reader) -> None:
    for path, why in REMOVED_KEYS.items():
        table = reader.data.get(path[0])
        if isinstance(table, dict) and path[1] in table:
            raise reader.fail(path, f"is no longer a robot description key: {why}")


def parse_robot(text: str, source: str = "<robot>") -> Robot:
    """Build a ``Robot`` from TOML text; ``source`` names it in error messages."""
    deep = too_deep(text)
    if deep is not None:
        raise RobotError(f"{source} {deep}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RobotError(f"{source}: not valid TOML ({exc}): fix the syntax there") from None
    reader = _Reader(data, text, source)
    _refuse_removed(reader)
    reader.check_keys(SCHEMA, data)
    kind = reader.get(("kind",), str)
    if kind not in ("snake", "trident", "car"):
        raise reader.fail(("kind",), f'must be "snake", "trident" or "car", not {quoted(kind)}')
    joints_raw = reader.get(("joints",), list)
    joints = tuple(_joint(reader, i) for i in range(len(joints_raw)))
    ids = [j.servo_id for j in joints]
    for i, sid in enumerate(ids):
        if sid in ids[:i]:
            raise reader.fail(
                ("joints", str(i), "servo_id"),
                f"{sid} is used twice: give each joint its own servo ID",
            )

    model = reader.get(("servo", "model"), str, "AX-12A")
    if model not in SERVO_MAX_RPM and "max_speed_rpm" not in data.get("servo", {}):
        raise reader.fail(
            ("servo", "model"),
            f"{quoted(model)} is unknown: use one of "
            f"{', '.join(SERVO_MAX_RPM)} or give servo.max_speed_rpm",
        )
    datasheet = SERVO_MAX_RPM.get(model)
    rpm = reader.number(
        ("servo", "max_speed_rpm"),
        0.0,
        datasheet,
        strictly=True,
        high=datasheet,
        why_high=f" rpm, the {model}'s no-load speed in its datasheet",
    )
    speed_limit = reader.get(("servo", "speed_limit"), str, SPEED_LIMITS[0])
    if speed_limit not in SPEED_LIMITS:
        raise reader.fail(
            ("servo", "speed_limit"),
            f"must be {' or '.join(map(quoted, SPEED_LIMITS))}, not {quoted(speed_limit)}",
        )
    common: dict[str, Any] = dict(
        name=reader.get(("name",), str),
        kind=kind,
        joints=joints,
        servo_model=model,
        max_speed_rad_s=rpm * 2.0 * math.pi / 60.0,
        friction=_friction(reader),
        description=reader.get(("description",), str, ""),
        physics=_physics(reader),
        torque_limit=_torque_limit(reader),
        speed_limit=speed_limit,
        source=source,
    )
    if kind == "snake":
        links = reader.integer(("geometry", "links"), 2, MAX_LINKS)
        if len(joints) != links - 1:
            raise reader.fail(
                ("joints",),
                f"has {len(joints)} entries but a {links}-link snake "
                f"has {links - 1} joints: add or remove [[joints]] tables",
            )
        return Robot(
            l=reader.number(("geometry", "half_link"), 0.0, strictly=True), links=links, **common
        )
    if kind == "car":
        if len(joints) != 1:
            raise reader.fail(
                ("joints",), f"has {len(joints)} entries but a car has 1 joint (its steering)"
            )
        return Robot(l=reader.number(("geometry", "wheelbase"), 0.0, strictly=True), **common)
    alphas = reader.get(("geometry", "alphas_deg"), list)
    if len(alphas) != 3 or not all(isinstance(a, int | float) for a in alphas):
        raise reader.fail(("geometry", "alphas_deg"), f"must be 3 angles in degrees, not {alphas}")
    if len(joints) != 3:
        raise reader.fail(("joints",), f"has {len(joints)} entries but a trident has 3 joints")
    return Robot(
        l=reader.number(("geometry", "arm_length"), 0.0, strictly=True),
        r=reader.number(("geometry", "base_radius"), 0.0),
        alphas=tuple(math.radians(float(a)) for a in alphas),
        links=4,
        **common,
    )


def builtin_text(name: str) -> str:
    """The TOML text of the built-in robot ``name`` (one of ``BUILTIN_ROBOTS``)."""
    return resources.files("snakebot.model.robots").joinpath(f"{name}.toml").read_text()


@functools.cache
def _builtin(name: str) -> Robot:
    """A built-in robot, read once per process (a Robot is immutable; a search's every run
    builds an emulated bus from one)."""
    return parse_robot(builtin_text(name), source=name)


def load_robot(name_or_path: str | Path) -> Robot:
    """A built-in robot by name (``snake3``, ``trident``, ``snake5``) or a TOML file path."""
    text_name = str(name_or_path)
    if text_name in BUILTIN_ROBOTS:
        return _builtin(text_name)
    path = Path(name_or_path)
    if not path.is_file():
        raise RobotError(
            f"no robot {quoted(text_name)}: give a built-in name ({', '.join(BUILTIN_ROBOTS)}) "
            "or the path of a robot .toml file"
        )
    try:
        raw = read_bounded(path, MAX_FILE_BYTES, "robot description")
    except UnreadableInput as exc:
        raise RobotError(str(exc)) from None
    except OSError as exc:
        raise RobotError(f"cannot read robot file {path}: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RobotError(
            f"{path} is not UTF-8 text (byte {exc.start}): save the robot file as UTF-8"
        ) from None
    return parse_robot(text, source=str(path))


def _brief(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."
