"""The firmware image: read a ``.bin``, ``.hex`` or ``.elf`` (``formats``), check it fits
the CM-530's application area and looks like an image linked for it, and compute the
bootloader's checksum.

The board facts come from the linker script ``firmware/boards/cm530/cm530.ld`` (the one
source of the memory layout): the application starts at the FLASH region's origin
(0x08003000, after the 12 KB ROBOTIS bootloader) and may run to the end of flash (the
end of the last flash region, 0x08080000), so the bootloader accepts at most 500 KB.
Our own firmware stops short of that (its table store, gait library and limits take the
flash above 0x0801D000), but
another application may use the whole area. When the linker script is not there (snakebot
installed without its repository) the numbers in :data:`FALLBACK_LAYOUT` are used.

Our images carry an identity block (``firmware/hal/hal_image.h``: the board they were
built for, the firmware version, their length) whose address is in the vector table's
entry 7; :func:`image_info` reads it and :func:`load_image` refuses an image for another
board (the qemu build links at the same address but is not a CM-530 image).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from pathlib import Path

from snakebot.facts.boards import APP_BASE
from snakebot.facts.memory import CM530_FLASH_SIZE, CM530_RAM_SIZE, FLASH_BASE, RAM_BASE
from snakebot.link.flash.errors import ImageError
from snakebot.link.flash.formats import elf_chunks, flat_image, hex_chunks, kind_of
from snakebot.paths import REPO_ROOT
from snakebot.userfiles import FileTooLarge, UnreadableInput, read_bounded

BOARD = "cm530"
"""The board `snakebot flash` programs: the firmware's board directory and the name its
images carry in their identity block."""

BOARD_LINKER_SCRIPT = REPO_ROOT / "firmware" / "boards" / BOARD / f"{BOARD}.ld"

STACK_ALIGN = 8
"""The initial stack pointer's alignment: the Arm procedure call standard (AAPCS) wants
the stack 8-byte aligned at every public interface, the first call from reset included."""

INFO_VECTOR = 7
"""The vector table entry (a reserved one on Cortex-M3) holding the identity block's address."""

INFO_MAGIC = b"SNKI"
INFO_VERSION = 1
_INFO = struct.Struct("<4sBBHI8s")  # hal_image_info_t (firmware/hal/hal_image.h)

SRAM_BASE = RAM_BASE
"""Regions from FLASH_BASE up to here are flash."""

FILE_MAX = 32 * 1024 * 1024
"""The largest firmware file read: an ELF with its debugging information is many times
its image."""


@dataclass(frozen=True)
class BoardLayout:
    """Where an application image goes on the board, and where its stack may point."""

    app_base: int  # first flash address of the application (the vector table)
    flash_end: int  # one past the last flash address
    ram_base: int
    ram_end: int  # one past the last RAM address
    source: str  # where these numbers came from
    board: str = BOARD  # the name an image for it carries

    @property
    def app_size(self) -> int:
        """The most bytes the bootloader can take (the application area)."""
        return self.flash_end - self.app_base


FALLBACK_LAYOUT = BoardLayout(
    app_base=APP_BASE,
    flash_end=FLASH_BASE + CM530_FLASH_SIZE,
    ram_base=SRAM_BASE,
    ram_end=SRAM_BASE + CM530_RAM_SIZE,
    source="built-in CM-530 figures (cm530.ld not found)",
)

_REGION = re.compile(
    r"^\s*(\w+)\s*\(([a-z!]*)\)\s*:\s*ORIGIN\s*=\s*(0x[0-9a-fA-F]+|\d+)\s*,"
    r"\s*LENGTH\s*=\s*(0x[0-9a-fA-F]+|\d+)\s*([KM]?)",
    re.MULTILINE,
)


def _number(text: str, suffix: str = "") -> int:
    value = int(text, 0)
    return value * {"": 1, "K": 1024, "M": 1024 * 1024}[suffix]


def board_layout(linker_script: Path = BOARD_LINKER_SCRIPT) -> BoardLayout:
    """The CM-530 layout read from its linker script's MEMORY regions (FLASH, RAM, and any
    other flash region such as the gait-table store); the fallback if the file is absent."""
    try:
        text = linker_script.read_text()
    except OSError:
        return FALLBACK_LAYOUT
    regions = {
        name: (_number(origin), _number(length, suffix))
        for name, _attrs, origin, length, suffix in _REGION.findall(text)
    }
    if "FLASH" not in regions or "RAM" not in regions:
        raise ImageError(
            f"{linker_script} has no FLASH and RAM regions in its MEMORY block: "
            "fix the linker script"
        )
    flash_ends = [o + n for o, n in regions.values() if FLASH_BASE <= o < SRAM_BASE]
    ram_origin, ram_length = regions["RAM"]
    return BoardLayout(
        app_base=regions["FLASH"][0],
        flash_end=max(flash_ends),
        ram_base=ram_origin,
        ram_end=ram_origin + ram_length,
        source=str(linker_script),
    )


@dataclass(frozen=True)
class ImageInfo:
    """An image's identity block (``hal_image_info_t``)."""

    board: str
    firmware_version: int
    image_bytes: int  # the length the image says it has
    address: int  # where the block lies in flash


def image_info(data: bytes, app_base: int) -> ImageInfo | None:
    """The identity block of the image ``data`` (linked at ``app_base``), or None if the
    image has none (not ours, or older than the block)."""
    if len(data) < 4 * (INFO_VECTOR + 1):
        return None
    address = int.from_bytes(data[4 * INFO_VECTOR : 4 * INFO_VECTOR + 4], "little")
    offset = address - app_base
    if not 0 <= offset <= len(data) - _INFO.size:
        return None
    magic, version, fw_version, _reserved, nbytes, board = _INFO.unpack_from(data, offset)
    if magic != INFO_MAGIC or version != INFO_VERSION:
        return None
    name = board.split(b"\0", 1)[0].decode("ascii", "replace")
    return ImageInfo(board=name, firmware_version=fw_version, image_bytes=nbytes, address=address)


def identity_block(board: str, firmware_version: int, image_bytes: int) -> bytes:
    """The bytes of an identity block (``hal_image_info_t``): what the firmware build puts
    after the vector table, for tools and tests that make images another way."""
    name = board.encode("ascii")
    if len(name) > 8:
        raise ValueError(f"board name {board!r} is longer than 8 bytes")
    return _INFO.pack(INFO_MAGIC, INFO_VERSION, firmware_version, 0, image_bytes, name)


def checksum(data: bytes) -> int:
    """The ROBOTIS loader's checksum: the low byte of the sum of all bytes."""
    return sum(data) & 0xFF


def load_image(
    path: str | Path, layout: BoardLayout | None = None, *, check_vectors: bool = True
) -> bytes:
    """Read the image at ``path`` (a raw .bin, an Intel HEX or an ELF file, told apart by
    their content) as the bytes from the application base on, and check it can go through
    the bootloader.

    Refuses a missing or empty file, a HEX or ELF file that is damaged or places bytes
    outside the application area, an image bigger than that area, and, unless ``check_vectors`` is
    False, an image the board would not start: its vector table must fit the board
    (initial stack pointer inside RAM and 8-byte aligned, reset handler a Thumb address in
    the image's code, after its vector table and identity block) and its identity block
    must name this board and the image's true length. Such an image is linked for another
    address or board, or cut short: the bootloader would store it and the CPU fault.
    """
    path = Path(path)
    layout = layout or board_layout()
    try:
        data = read_bounded(path, FILE_MAX, "firmware file")
    except FileTooLarge as exc:
        raise ImageError(_too_big(path, exc.size, layout)) from None
    except UnreadableInput as exc:
        raise ImageError(str(exc)) from None
    except FileNotFoundError:
        raise ImageError(
            f"firmware image {path} not found: build it with make firmware (it writes "
            "build/cm530/firmware.bin) or give the path of a .bin, .hex or .elf file"
        ) from None
    except IsADirectoryError:
        raise ImageError(
            f"{path} is a directory: give the firmware's .bin, .hex or .elf file"
        ) from None
    except OSError as exc:
        raise ImageError(f"cannot read firmware image {path}: {exc.strerror or exc}") from exc
    if not data:
        raise ImageError(
            f"firmware image {path} is empty: rebuild it (make firmware) and check the build log"
        )
    kind = kind_of(path, data)
    if kind != "bin":
        chunks = elf_chunks(path, data) if kind == "elf" else hex_chunks(path, data)
        data = flat_image(path, chunks, layout.app_base, layout.flash_end)
    elif len(data) > layout.app_size:
        raise ImageError(_too_big(path, len(data), layout))
    if check_vectors:
        _check_vectors(path, data, layout)
    return data


def _too_big(path: Path, size: int | None, layout: BoardLayout) -> str:
    bytes_ = f"{size} bytes" if size is not None else "endless (a device?)"
    return (
        f"firmware image {path} is {bytes_}, more than the {layout.app_size} "
        f"bytes ({layout.app_size // 1024} KB) of the CM-530's application area "
        f"0x{layout.app_base:08X}-0x{layout.flash_end - 1:08X}: make the firmware smaller"
    )


def _check_vectors(path: Path, data: bytes, layout: BoardLayout) -> None:
    force = "(skip this check to flash it anyway)"
    if len(data) < 8:
        raise ImageError(
            f"firmware image {path} is only {len(data)} bytes, too short to hold a Cortex-M "
            "vector table: give the .bin of a real build (or skip this check for raw data)"
        ).about("force")
    sp = int.from_bytes(data[0:4], "little")
    reset = int.from_bytes(data[4:8], "little")
    if not layout.ram_base < sp <= layout.ram_end:
        raise ImageError(
            f"firmware image {path} starts with stack pointer 0x{sp:08X}, outside the "
            f"CM-530's RAM 0x{layout.ram_base:08X}-0x{layout.ram_end:08X}: this is not a "
            f"Cortex-M image for this board {force}"
        ).about("force")
    if sp % STACK_ALIGN:
        raise ImageError(
            f"firmware image {path} starts with stack pointer 0x{sp:08X}, not {STACK_ALIGN}-byte "
            f"aligned as the first call from reset needs: the image is damaged or not built "
            f"for a Cortex-M {force}"
        ).about("force")
    entry = reset & ~1
    code_end = layout.app_base + len(data)
    if not (reset & 1 and layout.app_base <= entry < code_end):
        raise ImageError(
            f"firmware image {path} has its reset handler at 0x{reset:08X}, not a Thumb "
            f"address inside the image at 0x{layout.app_base:08X}: it was linked for "
            "another address (the bootloader starts the application at "
            f"0x{layout.app_base:08X}; build with boards/cm530/cm530.ld) {force}"
        ).about("force")
    info = image_info(data, layout.app_base)
    if info is None:
        raise ImageError(
            f"firmware image {path} has no snakebot identity block (vector entry "
            f"{INFO_VECTOR} pointing at {INFO_MAGIC.decode()}): build it with make firmware, "
            f"or {force[1:-1]} if it is another program for the CM-530"
        ).about("force")
    if info.board != layout.board:
        raise ImageError(
            f"firmware image {path} was built for board {info.board!r}, not {layout.board!r}: "
            f"give build/{layout.board}/firmware.bin"
        ).about("force")
    if info.image_bytes != len(data):
        raise ImageError(
            f"firmware image {path} is {len(data)} bytes but says it is {info.image_bytes}: "
            "it is cut short or has bytes appended; rebuild it (make firmware)"
        ).about("force")
    code_start = info.address + _INFO.size
    if entry < code_start:
        raise ImageError(
            f"firmware image {path} has its reset handler at 0x{reset:08X}, inside its vector "
            f"table or identity block (code starts at 0x{code_start:08X}): the image is "
            f"damaged {force}"
        ).about("force")
