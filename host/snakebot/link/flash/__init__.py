"""Flashing the CM-530 through the ROBOTIS bootloader on its PC link.

    from snakebot.link.flash import flash, load_image
    image = load_image("build/cm530/firmware.bin")
    with open_port("/dev/ttyUSB0", PC_LINK_BAUD, timeout=0) as port:
        result = flash(port, image, say=print)

``bootloader`` holds the bootloader's wire sequence as operations on an open port;
``image`` reads and checks the image (``formats``: .bin, .hex or .elf); ``report`` reads
the bootloader's ``Checksum:`` report; ``verify`` checks, after GO, that the new
firmware answers and holds what was sent; ``library_backup`` keeps the controller's gait
library across a flash; ``settings`` the named, environment-overridable timeouts.

May import: as the ``link`` layer (``link.transport``, ``link.controller``, ``model``,
``formats``, ``facts``, the package root); never ``sim``.
"""

from __future__ import annotations

from snakebot.link.flash.bootloader import (
    FlashResult,
    enter_bootloader,
    flash,
    read_checksum,
    send_image,
    start_application,
    start_load,
)
from snakebot.link.flash.errors import FlashError, FlashSettingError, ImageError
from snakebot.link.flash.image import BoardLayout, board_layout, checksum, load_image
from snakebot.link.flash.report import ChecksumMatch, ChecksumReport, parse_report, verify_checksum
from snakebot.link.flash.settings import FlashTimeouts

__all__ = [
    "BoardLayout",
    "ChecksumMatch",
    "ChecksumReport",
    "FlashError",
    "FlashResult",
    "FlashSettingError",
    "FlashTimeouts",
    "ImageError",
    "board_layout",
    "checksum",
    "enter_bootloader",
    "flash",
    "load_image",
    "parse_report",
    "read_checksum",
    "send_image",
    "start_application",
    "start_load",
    "verify_checksum",
]
