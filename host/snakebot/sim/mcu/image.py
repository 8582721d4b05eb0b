"""Which images the emulated CM-530 runs: the application image as the ROBOTIS bootloader
receives it (the bytes from 0x08003000 on), checked the way the board would fail on it,
but named: an empty image, one without snakebot's identity block or built for another
board, one shorter than its identity block says (cut off on the way), and one whose stack
pointer is not in RAM or whose reset vector is not a Thumb address inside the image. The
file formats (.bin, .hex, .elf) and the identity block are read by
:mod:`snakebot.link.flash.image`, the one place that knows them.
"""

from __future__ import annotations

import os
from pathlib import Path

from snakebot.errors import SnakebotError
from snakebot.facts.boards import APP_BASE
from snakebot.facts.memory import CM530_FLASH_SIZE, CM530_RAM_SIZE, FLASH_BASE, RAM_BASE
from snakebot.link.flash.image import image_info, load_image
from snakebot.sim.mcu.errors import ImageError

BOARD = "cm530"
RAM_END = RAM_BASE + CM530_RAM_SIZE
FLASH_END = FLASH_BASE + CM530_FLASH_SIZE


def check_image(data: bytes, source: str = "the image") -> bytes:
    """``data`` if the emulated CM-530 can start it, else :class:`ImageError` saying why."""
    if not data:
        raise ImageError(f"{source} is empty: send the .bin that `make firmware` builds")
    if len(data) < 8:
        raise ImageError(f"{source} is {len(data)} bytes, too short for a vector table")
    info = image_info(data, APP_BASE)
    if info is None:
        raise ImageError(
            f"{source} has no snakebot identity block: it is not a CM-530 firmware image "
            "(build build/cm530/firmware.bin with `make firmware`)"
        )
    if info.board != BOARD:
        raise ImageError(
            f"{source} was built for the {info.board} board, not the CM-530: give the "
            "CM-530's image, build/cm530/firmware.bin from `make firmware`"
        )
    if len(data) < info.image_bytes:
        raise ImageError(
            f"{source} is truncated: {len(data)} of the {info.image_bytes} bytes its identity "
            "block names arrived; send it again"
        )
    sp = int.from_bytes(data[0:4], "little")
    reset = int.from_bytes(data[4:8], "little")
    if not RAM_BASE < sp <= RAM_END:
        raise ImageError(
            f"{source} starts with stack pointer 0x{sp:08X}, outside the CM-530's RAM: "
            "not a firmware linked for this board"
        )
    end = APP_BASE + len(data)
    if not (reset & 1 and APP_BASE < reset & ~1 < min(end, FLASH_END)):
        raise ImageError(
            f"{source}'s reset vector 0x{reset:08X} is not a Thumb address inside the image "
            f"(0x{APP_BASE:08X}-0x{end - 1:08X}): the CPU would fault at once"
        )
    return data


def read_image(path: str | os.PathLike[str]) -> bytes:
    """The application bytes of the firmware file at ``path`` (.bin, .hex or .elf), checked
    with :func:`check_image`."""
    try:
        data = load_image(Path(path), check_vectors=False)
    except SnakebotError as exc:
        raise ImageError(str(exc)) from None
    return check_image(data, str(path))
