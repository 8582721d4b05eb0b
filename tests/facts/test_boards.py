"""The boards' Table Capacity on the host (``snakebot.facts.boards``) is what each board.h
sets, for every board the firmware is built for, and the largest board's is the largest
table the controller logic takes."""

from __future__ import annotations

from firmware_support import FIRMWARE, board_value

from snakebot.facts.boards import TABLE_CAPACITY, largest_board, smallest_board
from snakebot.formats.gaittable import MAX_TABLE_BYTES


def test_every_boards_capacity_is_its_board_h():
    boards = {p.parent.name for p in (FIRMWARE / "boards").glob("*/board.h")}
    assert set(TABLE_CAPACITY) == boards
    for name in boards:
        assert TABLE_CAPACITY[name] == board_value(name, "BOARD_TABLE_CAPACITY"), name


def test_smallest_and_largest_board():
    sizes = sorted(TABLE_CAPACITY.values())
    assert TABLE_CAPACITY[smallest_board()] == sizes[0] < sizes[-1]
    assert TABLE_CAPACITY[largest_board()] == sizes[-1] == MAX_TABLE_BYTES
