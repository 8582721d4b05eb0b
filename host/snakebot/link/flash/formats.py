"""Firmware files in the three forms a build gives: a raw ``.bin``, Intel HEX (read with
intelhex) and ELF (read with pyelftools), all turned into the same bytes: the image as it
lies in flash from the application base on, gaps filled with zeros as
``arm-none-eabi-objcopy -O binary`` fills them.

An Intel HEX or ELF file says where each byte goes, so it is refused when anything lies
outside the application area (below it is the ROBOTIS bootloader) or the image does not
begin at its base (the bootloader starts the application there).
"""

from __future__ import annotations

import io
from collections.abc import Iterable
from pathlib import Path

from elftools.common.exceptions import ELFError
from elftools.elf.elffile import ELFFile
from intelhex import IntelHex, IntelHexError

from snakebot.link.flash.errors import ImageError

ELF_MAGIC = b"\x7fELF"

GIVE = "give the build's .elf, .hex or .bin"

Chunk = tuple[int, bytes]
"""Bytes and the flash address of the first one."""


def looks_like_intel_hex(data: bytes) -> bool:
    """Whether ``data`` begins like an Intel HEX file (a ``:`` record of hex digits)."""
    line = data[:64].split(b"\n", 1)[0].rstrip(b"\r")
    return (
        len(line) > 1
        and line.startswith(b":")
        and all(c in b"0123456789ABCDEFabcdef" for c in line[1:])
    )


def kind_of(path: Path, data: bytes) -> str:
    """ "elf", "hex" or "bin": by the content, the name only where the content cannot tell."""
    if data.startswith(ELF_MAGIC):
        return "elf"
    if looks_like_intel_hex(data) or path.suffix.lower() in (".hex", ".ihex"):
        return "hex"
    if path.suffix.lower() in (".elf", ".axf"):
        raise ImageError(f"{path} is named like an ELF file but does not start like one: {GIVE}")
    return "bin"


def hex_chunks(path: Path, data: bytes) -> list[Chunk]:
    """The data records of an Intel HEX file, merged into runs of consecutive bytes."""
    try:
        ih = IntelHex(io.StringIO(data.decode("ascii")))
    except (IntelHexError, UnicodeDecodeError, ValueError) as exc:
        raise ImageError(
            f"{path} is not a valid Intel HEX file ({_first_line(exc)}): {GIVE}"
        ) from None
    return [(start, ih.tobinstr(start=start, end=stop - 1)) for start, stop in ih.segments()]


def elf_chunks(path: Path, data: bytes) -> list[Chunk]:
    """The loadable segments of an ELF file with bytes in the file, at their physical
    (load) addresses: initialised data is stored in flash after the code, not at its RAM
    address."""
    try:
        elf = ELFFile(io.BytesIO(data))
        if elf["e_machine"] != "EM_ARM":
            raise ImageError(
                f"{path} is an ELF file for {elf['e_machine']}, not for an Arm Cortex-M: "
                "give the firmware built for the CM-530"
            )
        chunks = []
        for seg in elf.iter_segments():
            if seg["p_type"] != "PT_LOAD" or seg["p_filesz"] == 0:
                continue
            blob = seg.data()
            if len(blob) < seg["p_filesz"]:
                raise ImageError(
                    f"{path} is cut short: a segment of {seg['p_filesz']} bytes has only "
                    f"{len(blob)} in the file; copy or rebuild it (make firmware)"
                )
            chunks.append((seg["p_paddr"], blob[: seg["p_filesz"]]))
        return chunks
    except (ELFError, ValueError, KeyError, OSError) as exc:
        raise ImageError(
            f"{path} is not a readable ELF file ({_first_line(exc)}): {GIVE}"
        ) from None


def flat_image(path: Path, chunks: Iterable[Chunk], base: int, end: int) -> bytes:
    """The chunks laid out from ``base``, gaps zero-filled; refused if any byte falls
    outside ``base``..``end`` or nothing lies at ``base``."""
    chunks = sorted((addr, blob) for addr, blob in chunks if blob)
    if not chunks:
        raise ImageError(f"{path} holds no bytes to load: {GIVE}")
    low = chunks[0][0]
    high = max(addr + len(blob) for addr, blob in chunks)
    if low < base or high > end:
        raise ImageError(
            f"{path} holds bytes at 0x{low:08X}-0x{high - 1:08X}, outside the CM-530's "
            f"application area 0x{base:08X}-0x{end - 1:08X} (below it is the bootloader): "
            "it was linked for another address; build with boards/cm530/cm530.ld"
        )
    if low != base:
        raise ImageError(
            f"{path} starts at 0x{low:08X}, not at the application base 0x{base:08X} where "
            "the bootloader starts it: it was linked for another address"
        )
    image = bytearray(high - base)
    for addr, blob in chunks:
        image[addr - base : addr - base + len(blob)] = blob
    return bytes(image)


def _first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]
