"""The boards the firmware is built for, and what the host needs to know of each: the
largest gait table (or program) it takes (its Table Capacity), the control tick, the PC
link's baud rate, where the application starts in flash, the crystal, the watchdog's
timeout and the flash page size.

Each board's ``firmware/boards/<name>/board.h`` (or a header of the board it includes)
sets ``BOARD_TABLE_CAPACITY``, ``BOARD_CONTROL_TICK_MS``, ``BOARD_PC_BAUD`` and
``BOARD_APP_BASE``; the cffi build (``_core_build.board_facts``) carries them into
``snakebot._core`` as ``BOARD_<NAME>_<FACT>``, so the numbers are written once, in the
firmware. A controller reports its own capacity as the Table Capacity register (Program
page). The controller's default ID is a fact of its control table
(:mod:`snakebot.facts.controller`, register ``ID``).
"""

from __future__ import annotations

from snakebot._core import lib

_PREFIX = "BOARD_"


def _by_board(fact: str) -> dict[str, int]:
    suffix = f"_{fact}"
    return {
        name[len(_PREFIX) : -len(suffix)].lower(): int(getattr(lib, name))
        for name in sorted(dir(lib))
        if name.startswith(_PREFIX) and name.endswith(suffix)
    }


def _common(fact: str) -> int:
    values = set(_by_board(fact).values())
    if len(values) != 1:  # pragma: no cover - a board.h that breaks the shared contract
        raise ImportError(f"the boards disagree on BOARD_{fact}: {sorted(values)}")
    return values.pop()


TABLE_CAPACITY: dict[str, int] = _by_board("TABLE_CAPACITY")
"""Table Capacity in bytes by board name (``cm530``, ``qemu``)."""

CONTROL_TICK_MS: int = _common("CONTROL_TICK_MS")
"""The controller's control tick in ms, the same on every board."""

PC_LINK_BAUD: int = _common("PC_BAUD")
"""The PC link's bit rate (USART3, 8N1), bootloader and application alike."""

APP_BASE: int = _common("APP_BASE")
"""Where the application starts in flash, behind the ROBOTIS bootloader."""

HSE_HZ: dict[str, int] = _by_board("HSE_HZ")
"""The crystal on each board (Hz), which the PLL multiplies up to the system clock."""

WATCHDOG_MS: int = _common("WATCHDOG_MS")
"""The independent watchdog's timeout the firmware programs (ms, at the nominal LSI)."""

FLASH_PAGE_SIZE: dict[str, int] = _by_board("FLASH_PAGE_SIZE")
"""Bytes in one erasable flash page, by board (2 KB on the STM32F103RE)."""


ROBOT_BOARD = "cm530"
"""The board a robot carries, the CM-530: the image ``snakebot flash`` writes, the board
``snakebot sim serve`` and the demo emulate unless told otherwise, and the one whose
capacity a plan fits when no controller or board is named."""

if ROBOT_BOARD not in TABLE_CAPACITY:  # pragma: no cover - a firmware/boards/ rename
    raise ImportError(f"no firmware/boards/{ROBOT_BOARD}: the robot's board is gone")


def smallest_board() -> str:
    """The board that holds the smallest table: what every board takes."""
    return min(TABLE_CAPACITY, key=lambda name: (TABLE_CAPACITY[name], name))


def largest_board() -> str:
    """The board that holds the largest table."""
    return max(TABLE_CAPACITY, key=lambda name: (TABLE_CAPACITY[name], name))
