"""The boards' figures the docs show (RAM, table capacity and arena, the CM-530's flash
map), read from firmware/boards/*/board.h, where they are written once, and rendered as
Markdown blocks that protocol/gen_headers.py splices into the docs between

    <!-- generated:board NAME (protocol/gen_headers.py) -->
    <!-- generated:end board NAME -->

so prose around them names the macros and never restates a number. Standard library
only, like the generator.
"""

from __future__ import annotations

import ast
import json
import operator
import re
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BOARDS = ROOT / "firmware" / "boards"
CONTROLLER_JSON = ROOT / "host" / "snakebot" / "facts" / "devices" / "data" / "controller.json"
TITLES = {"qemu": "QEMU", "cm530": "CM-530"}  # in the order the docs list them
KB = 1024

_OPS: dict[type, Callable[[int, int], int]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.floordiv,  # C's unsigned division
}


def board_value(board: str, name: str) -> int:
    """The number ``#define name`` stands for in firmware/boards/<board>/board.h: an
    expression of unsigned literals, casts to an unsigned type and the board's other
    numbers."""
    text = (BOARDS / board / "board.h").read_text()
    found = re.search(rf"^#define {name} (.+)$", text, re.M)
    if found is None:
        raise KeyError(f"{name} is not defined in boards/{board}/board.h")
    expr = re.sub(r"\((unsigned( long)?|uint32_t)\)", "", found[1].split("/*")[0])
    expr = re.sub(r"\b(0x[0-9A-Fa-f]+|\d+)[UuLl]*\b", r"\1", expr)

    def value(node: ast.AST) -> int:
        if isinstance(node, ast.Constant) and isinstance(node.value, int):
            return node.value
        if isinstance(node, ast.Name) and node.id.startswith("BOARD_"):
            return board_value(board, node.id)
        if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
            return _OPS[type(node.op)](value(node.left), value(node.right))
        raise ValueError(f"boards/{board}/board.h {name}: cannot evaluate {found[1]!r}")

    return value(ast.parse(expr.strip(), mode="eval").body)


def _kb(n: int) -> str:
    return f"{n // KB} KB" if n % KB == 0 else f"{n} B"


def _library_slots() -> int:
    return json.loads(CONTROLLER_JSON.read_text())["limits"]["max_library_slots"]


def _per_board(head: list[str], row: Callable[[str], list[str]]) -> str:
    """A Markdown table with the columns ``head`` and ``[title, *row(board)]`` per board."""
    lines = ["| " + " | ".join(["board", *head]) + " |", "|---" * (len(head) + 1) + "|"]
    for board, title in TITLES.items():
        lines.append("| " + " | ".join([title, *row(board)]) + " |")
    return "\n".join(lines)


def arena_table() -> str:
    """Per board: its RAM, Table Capacity, table arena, and whether an upload fits beside
    a playing table (protocol/controller.md, "Where a table is staged")."""

    def row(board: str) -> list[str]:
        capacity = board_value(board, "BOARD_TABLE_CAPACITY")
        arena = board_value(board, "BOARD_TABLE_ARENA")
        beside = (
            "always taken: the two never overlap"
            if arena >= 2 * capacity
            else f"taken while the playing table is at most {arena - capacity} bytes; "
            "refused otherwise"
        )
        return [_kb(board_value(board, "BOARD_RAM_SIZE")), str(capacity), str(arena), beside]

    return _per_board(["RAM", "Table Capacity", "arena", "an upload while a table plays"], row)


def board_table() -> str:
    """Per board: RAM, flash page, the largest table and where the committed table and the
    library are kept (docs/hardware.md, "Tables in RAM and flash")."""

    def row(board: str) -> list[str]:
        capacity = board_value(board, "BOARD_TABLE_CAPACITY")
        kept = (
            'in flash (`protocol/library.md`, "Where it lies")'
            if board_value(board, "BOARD_HAS_FLASH_STORE")
            else "in RAM only, lost at power-off (one library slot: the active table)"
        )
        return [
            _kb(board_value(board, "BOARD_RAM_SIZE")),
            _kb(board_value(board, "BOARD_FLASH_PAGE_SIZE")),
            f"{capacity} bytes ({_kb(capacity)})",
            _kb(board_value(board, "BOARD_TABLE_ARENA")),
            kept,
        ]

    head = ["RAM", "flash page", "Table Capacity", "table arena", "committed table, library"]
    return _per_board(head, row)


def cm530_flash_map() -> str:
    """The CM-530's flash from the committed table's store up (protocol/library.md)."""

    def v(name: str) -> int:
        return board_value("cm530", name)

    store, dir_base = v("BOARD_STORE_BASE"), v("BOARD_LIB_DIR_BASE")
    areas = _library_slots() + 1
    areas_base = dir_base + v("BOARD_LIB_DIR_SIZE")
    limits = v("BOARD_LIMITS_STORE_BASE")
    page = v("BOARD_FLASH_PAGE_SIZE")
    rows = [
        (store, v("BOARD_STORE_SIZE"), "the committed table, two copies (not the library)"),
        (dir_base, v("BOARD_LIB_DIR_SIZE"), "the directory: two copies"),
        (
            areas_base,
            areas * v("BOARD_LIB_AREA_SIZE"),
            f"{areas} data areas of {_kb(v('BOARD_LIB_AREA_SIZE'))}",
        ),
        (limits, v("BOARD_LIMITS_STORE_SIZE"), "the robot's limits (not the library)"),
    ]
    out = ["| flash | size | what | macro |", "|---|---|---|---|"]
    macros = [
        "BOARD_STORE_BASE",
        "BOARD_LIB_DIR_BASE",
        "BOARD_LIB_DIR_BASE + BOARD_LIB_DIR_SIZE",
        "BOARD_LIMITS_STORE_BASE",
    ]
    for (base, size, what), macro in zip(rows, macros, strict=True):
        assert size % page == 0, what
        out.append(
            f"| `0x{base:08X}`–`0x{base + size - 1:08X}` | {_kb(size)} | {what} | `{macro}` |"
        )
    return "\n".join(out)


# The F103's flash timings at their worst (datasheet: tERASE 20-40 ms a page, tPROG
# 40-70 us a half-word): what one step of a save can stall the CPU for.
ERASE_MS = (20, 40)
PROGRAM_US = (40, 70)


def _app_define(path: str, name: str) -> int:
    """A numeric #define of the firmware's app (e.g. STORE_SAVE_HALFWORDS in store.c)."""
    return int(re.search(rf"#define {name} (\d+)U", (ROOT / "firmware" / path).read_text())[1])


def save_steps() -> str:
    """The committed table's save on the CM-530, a step per tick (docs/hardware.md): the
    steps a table of the full capacity takes, each one's longest stall, and the time."""
    capacity = board_value("cm530", "BOARD_TABLE_CAPACITY")
    page = board_value("cm530", "BOARD_FLASH_PAGE_SIZE")
    tick = board_value("cm530", "BOARD_CONTROL_TICK_MS")
    halfwords = _app_define("app/store.c", "STORE_SAVE_HALFWORDS")
    header = _app_define("app/store_slots.h", "STORE_SLOTS_HEADER_BYTES")
    erases = -(-(header + capacity) // page)
    programs = -(-capacity // (2 * halfwords))
    low, high = (halfwords * us / 1000 for us in PROGRAM_US)
    steps = [
        (
            "read one slot's record to find the newest (a CRC of up to a whole table, no flash "
            "busy)",
            2,
            "about 5 ms of CPU",
            0.0,
        ),
        (
            "erase one page",
            erases,
            f"one page erase: {ERASE_MS[0]}-{ERASE_MS[1]} ms (tERASE)",
            ERASE_MS[1],
        ),
        (
            f"program {halfwords} half-words (`STORE_SAVE_HALFWORDS`)",
            programs,
            f"{halfwords} x {PROGRAM_US[0]}-{PROGRAM_US[1]} us = {low:.1f}-{high:.1f} ms",
            high,
        ),
        ("header, magic, read-back", 3, "6 half-words; then a CRC of the table", 0.0),
    ]
    out = [
        f"| step | ticks for a table of {capacity} bytes | longest stall of one step |",
        "|---|---|---|",
    ]
    out += [f"| {what} | {n} | {stall} |" for what, n, stall, _ in steps]
    seconds = sum(n * max(tick, ms) for _, n, _, ms in steps) / 1000
    out += [
        "",
        f"A whole save of a table of {capacity} bytes takes about {seconds:.1f} s of "
        f"{tick} ms ticks at worst.",
    ]
    return "\n".join(out)


BLOCKS: dict[str, Callable[[], str]] = {
    "save-steps": save_steps,
    "arena": arena_table,
    "boards": board_table,
    "cm530-flash": cm530_flash_map,
}
"""Each block by name: what renders it."""

DOCS = [
    ROOT / "protocol" / "controller.md",
    ROOT / "protocol" / "library.md",
    ROOT / "docs" / "hardware.md",
]
"""The docs that hold board blocks."""


def begin(name: str) -> str:
    return f"<!-- generated:board {name} (protocol/gen_headers.py) -->"


def end(name: str) -> str:
    return f"<!-- generated:end board {name} -->"


def splice(text: str) -> str:
    """``text`` with each board block it holds rendered afresh."""
    for name, render in BLOCKS.items():
        if begin(name) not in text:
            continue
        start = text.index(begin(name)) + len(begin(name))
        stop = text.index(end(name))
        text = f"{text[:start]}\n{render()}\n{text[stop:]}"
    return text


def outside_blocks(text: str) -> str:
    """``text`` without its generated parts (board blocks and gen_headers' tables), for
    checks of what the prose states."""
    text = re.sub(
        r"<!-- generated:board (\S+) .*?<!-- generated:end board \1 -->", "", text, flags=re.S
    )
    return re.sub(r"<!-- generated:begin .*?<!-- generated:end -->", "", text, flags=re.S)


def rendered() -> dict[Path, str]:
    """Each doc holding board blocks, with them rendered afresh."""
    return {path: splice(path.read_text()) for path in DOCS}
