"""Which images the emulated CM-530 starts, and the one-line reason it refuses the others
(another board's, empty, cut short, a stack pointer outside RAM, a reset vector outside
the image)."""

from __future__ import annotations

import pytest

from snakebot.firmware import image as firmware_image
from snakebot.sim.mcu.errors import ImageError
from snakebot.sim.mcu.image import check_image


def _image(board: str) -> bytes:
    path = firmware_image(board, "firmware.bin")
    if not path.is_file():
        pytest.skip(f"build/{board}/firmware.bin is not built: make firmware")
    return path.read_bytes()


def test_the_cm530_image_passes_with_or_without_the_checksum_byte():
    data = _image("cm530")
    assert check_image(data) == data
    assert check_image(data + bytes([sum(data) & 0xFF])) is not None  # RoboPlus's extra byte


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda d: b"", "empty"),
        (lambda d: d[: len(d) // 2], "truncated"),
        (lambda d: d[:4] + (0x08000101).to_bytes(4, "little") + d[8:], "reset vector"),
        (lambda d: (0x30000000).to_bytes(4, "little") + d[4:], "stack pointer"),
        (lambda d: bytes(len(d)), "no snakebot identity block"),
    ],
)
def test_images_the_board_cannot_start_are_refused_in_one_line(make, words):
    with pytest.raises(ImageError, match=words) as info:
        check_image(make(_image("cm530")))
    assert "\n" not in str(info.value)


def test_the_qemu_boards_image_is_refused_as_another_boards():
    with pytest.raises(ImageError, match="built for the qemu board"):
        check_image(_image("qemu"))
