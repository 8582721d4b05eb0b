"""The boards' figures in the docs come from firmware/boards/*/board.h and nowhere else:
the tables protocol/gen_headers.py generates from board.h (protocol/board_figures.py) are
current, and the prose around them restates no board figure (no flash address, table
capacity, arena or store size that board.h holds), so changing board.h cannot leave a
doc stating a stale number."""

from __future__ import annotations

import re

import pytest
from firmware_support import board_figures

from snakebot.paths import REPO_ROOT

BF = board_figures()
PROSE = [*BF.DOCS, REPO_ROOT / "protocol" / "program.md"]
FIGURES = (  # macros whose values a doc might restate
    "BOARD_TABLE_CAPACITY",
    "BOARD_TABLE_ARENA",
    "BOARD_STORE_SIZE",
    "BOARD_LIB_AREA_SIZE",
)


def board_defines() -> dict[str, dict[str, int]]:
    """Every numeric #define of every board.h: board -> name -> value."""
    out: dict[str, dict[str, int]] = {}
    for header in sorted(BF.BOARDS.glob("*/board.h")):
        board = header.parent.name
        names = re.findall(r"^#define (BOARD_\w+) ", header.read_text(), re.M)
        values = {}
        for name in names:
            try:
                values[name] = BF.board_value(board, name)
            except (ValueError, SyntaxError):
                continue  # a string, a pin list, a register base
        out[board] = values
    return out


def test_the_generated_board_tables_are_current():
    for path, text in BF.rendered().items():
        assert path.read_text() == text, f"{path}: run python protocol/gen_headers.py"


def test_the_cm530_flash_map_covers_the_library_and_stores_without_gaps():
    rows = re.findall(r"`0x([0-9A-F]{8})`–`0x([0-9A-F]{8})`", BF.cm530_flash_map())
    spans = [(int(a, 16), int(b, 16) + 1) for a, b in rows]
    assert spans[0][0] == BF.board_value("cm530", "BOARD_STORE_BASE")
    assert all(end == start for (_, end), (start, _) in zip(spans, spans[1:], strict=False))
    limits = BF.board_value("cm530", "BOARD_LIMITS_STORE_BASE")
    assert spans[-1] == (limits, limits + BF.board_value("cm530", "BOARD_LIMITS_STORE_SIZE"))


@pytest.mark.parametrize("path", PROSE, ids=lambda p: p.name)
def test_the_prose_restates_no_board_figure(path):
    prose = BF.outside_blocks(path.read_text())
    defines = board_defines()
    addresses = {v for values in defines.values() for v in values.values() if v >= 0x08000000}
    for found in re.findall(r"0x0?8[0-9A-Fa-f]{6}\b", prose):
        # an address the prose may name: where a board's image starts, as board.h says
        assert int(found, 16) in addresses, f"{path.name} states flash address {found}"
    figures = {values[n] for values in defines.values() for n in FIGURES if n in values}
    for value in figures:
        kb = f"{value // 1024} KB" if value % 1024 == 0 else None
        stated = re.search(rf"(?<![\w.]){value}(?![\w.])", prose) or (
            kb and re.search(rf"(?<![\w.]){kb}", prose)
        )
        assert not stated, (
            f"{path.name} states {stated[0]!r}, a board.h figure: name the macro, or put it "
            "in a table protocol/board_figures.py generates"
        )
