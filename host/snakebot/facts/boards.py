"""The boards the firmware is built for, and what the host needs to know of each: the
largest gait table (or program) it takes, its Table Capacity.

Each board's ``firmware/boards/<name>/board.h`` sets ``BOARD_TABLE_CAPACITY``; the cffi
build (``_core_build.board_facts``) carries it into ``snakebot._core`` as
``BOARD_<NAME>_TABLE_CAPACITY``, so the numbers are written once, in the firmware. A
controller reports its own as the Table Capacity register (Program page).
"""

from __future__ import annotations

from snakebot._core import lib

_PREFIX, _SUFFIX = "BOARD_", "_TABLE_CAPACITY"

TABLE_CAPACITY: dict[str, int] = {
    name[len(_PREFIX) : -len(_SUFFIX)].lower(): int(getattr(lib, name))
    for name in sorted(dir(lib))
    if name.startswith(_PREFIX) and name.endswith(_SUFFIX)
}
"""Table Capacity in bytes by board name (``cm530``, ``qemu``)."""


def smallest_board() -> str:
    """The board that holds the smallest table: what every board takes."""
    return min(TABLE_CAPACITY, key=lambda name: (TABLE_CAPACITY[name], name))


def largest_board() -> str:
    """The board that holds the largest table."""
    return max(TABLE_CAPACITY, key=lambda name: (TABLE_CAPACITY[name], name))
