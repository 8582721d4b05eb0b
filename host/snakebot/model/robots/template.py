"""A new robot file to start from: a built-in robot's values, every key explained.

The comments are the meanings in :mod:`snakebot.model.robots.schema` (the ones the loader
checks against); an optional key or table the built-in robot leaves out is written
commented out, with its default or an example, so that every key is there to read.
"""

from __future__ import annotations

import sys
import textwrap
from typing import Any

import tomlkit

if sys.version_info >= (3, 11):
    import tomllib
else:  # the same parser as a package (a dependency on Python 3.10 only)
    import tomli as tomllib

from snakebot.errors import quoted
from snakebot.model.robots.loader import BUILTIN_ROBOTS, builtin_text, parse_robot
from snakebot.model.robots.model import RobotError, joint_name
from snakebot.model.robots.schema import MAX_LINKS, MAX_SERVO_ID, TABLES, Table

WIDTH = 88


def _comment_lines(text: str) -> list[str]:
    return textwrap.wrap(text, WIDTH - 2) or [""]


def _values(like: str, links: int | None) -> dict[str, Any]:
    """The built-in robot ``like``'s keys and values, with ``links`` links if given (a
    snake's joints are then cut or extended: each new joint as the last, its own ID)."""
    if like not in BUILTIN_ROBOTS:
        raise RobotError(
            f"no built-in robot {quoted(like)}: start from one of {', '.join(BUILTIN_ROBOTS)}"
        ).about("like")
    data = tomllib.loads(builtin_text(like))
    if links is None:
        return data
    if data["kind"] != "snake":
        raise RobotError(
            f"a {data['kind']} has a fixed number of links: give a number of links only "
            "for a snake (snake3, snake5)"
        ).about("links")
    if not 2 <= links <= MAX_LINKS:
        raise RobotError(
            f"a snake has 2 to {MAX_LINKS} links, not {links}: give a number in that range"
        ).about("links")
    joints = data["joints"][: links - 1]
    while len(joints) < links - 1:
        used = {j["servo_id"] for j in joints}
        new_id = max(used) + 1
        if new_id > MAX_SERVO_ID:
            new_id = min(set(range(MAX_SERVO_ID + 1)) - used)
        joints.append({**joints[-1], "name": joint_name(len(joints)), "servo_id": new_id})
    if links != data["geometry"]["links"]:
        servos = f"{links - 1} servo{'s' if links > 2 else ''}"
        data["description"] = f"{links}-link snake on {servos}, after {like}"
    data["joints"] = joints
    data["geometry"]["links"] = links
    return data


def _fill(
    target: tomlkit.items.Table | tomlkit.TOMLDocument, table: Table, values: dict[str, Any]
) -> None:
    for key, about in table.keys.items():
        if key not in values and about.example is None:
            continue  # a key of another kind of robot (a trident's arms on a snake)
        for line in _comment_lines(about.meaning):
            target.add(tomlkit.comment(line))
        if key in values:
            target.add(key, values[key])
        else:
            target.add(tomlkit.comment(tomlkit.dumps({key: about.example}).strip()))


def _left_out(name: str, table: Table) -> list[str]:
    """An optional table the robot leaves out, as comment lines: its meaning, then its
    header and keys commented out."""
    lines = [f"# {line}" for line in _comment_lines(table.meaning)]
    lines.append(f"# [{name}]")
    for key, about in table.keys.items():
        lines += [f"#   {line}" for line in _comment_lines(about.meaning)]
        lines.append(f"# {tomlkit.dumps({key: about.example}).strip()}")
    return lines


def robot_file_text(name: str, like: str = "snake5", links: int | None = None) -> str:
    """A robot file named ``name`` with the values of the built-in robot ``like`` (and
    ``links`` links for a snake), each key under a comment saying what it is, in what
    unit. The result is checked by the loader before it is returned."""
    data = _values(like, links)
    data["name"] = name
    described = parse_robot(builtin_text(like), source=like)
    doc = tomlkit.document()
    header = (
        f"{name}: a robot description for snakebot, made from the built-in robot {like}, "
        f"{described.description}. Each key's meaning and unit is in the comment above "
        "it; a line '# key = value' is an optional key left out: remove the '# ' to set "
        "it. Measure your robot and change the values; `snakebot robot calibrate` "
        "measures each joint's zero tick and sign, `snakebot model info` checks the file."
    )
    for line in _comment_lines(header):
        doc.add(tomlkit.comment(line))
    doc.add(tomlkit.nl())
    _fill(doc, TABLES[""], data)
    tail: list[str] = []
    for table_name, table in TABLES.items():
        if not table_name:
            continue
        if table_name not in data:
            if table.optional:
                tail += ["", *_left_out(table_name, table)]
            continue
        items = data[table_name] if table.array else [data[table_name]]
        entries = []
        for n, item in enumerate(items):
            entry = tomlkit.table()
            if n == 0:  # the table's meaning under its (first) header
                for line in _comment_lines(table.meaning):
                    entry.add(tomlkit.comment(line))
            _fill(entry, table, item)
            entries.append(entry)
        doc.add(tomlkit.nl())
        doc.add(table_name, tomlkit.aot() if table.array else entries[0])
        if table.array:
            for entry in entries:
                doc[table_name].append(entry)
    text = tomlkit.dumps(doc) + "".join(f"{line}\n" for line in tail)
    parse_robot(text, source=name)  # what is written is a robot the loader takes
    return text
