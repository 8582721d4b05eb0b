"""Reading the CM-530's memory layout from its linker script, and the image checks."""

from __future__ import annotations

import pytest

from snakebot.flash import FlashTimeouts, ImageError, board_layout, checksum, load_image
from snakebot.flash.errors import FlashError, FlashSettingError
from snakebot.flash.image import FALLBACK_LAYOUT
from snakebot.flash.loader import ChecksumReport, verify_checksum


def test_layout_comes_from_the_cm530_linker_script():
    layout = board_layout()
    assert layout.source.endswith("firmware/boards/cm530/cm530.ld")
    assert layout.app_base == 0x08003000
    assert layout.flash_end == 0x08080000  # the gait-table store runs to the end of flash
    assert layout.app_size == 500 * 1024
    assert (layout.ram_base, layout.ram_end) == (0x20000000, 0x20010000)


def test_layout_follows_an_edited_linker_script(tmp_path):
    script = tmp_path / "board.ld"
    script.write_text(
        "MEMORY\n{\n    FLASH (rx) : ORIGIN = 0x08004000, LENGTH = 100K\n"
        "    RAM (rwx) : ORIGIN = 0x20000000, LENGTH = 0x5000\n}\n"
    )
    layout = board_layout(script)
    assert layout.app_base == 0x08004000
    assert layout.app_size == 100 * 1024
    assert layout.ram_end == 0x20005000
    image = tmp_path / "fw.bin"
    image.write_bytes(
        (0x20005000).to_bytes(4, "little") + (0x08004011).to_bytes(4, "little") + bytes(100)
    )
    assert load_image(image, layout) == image.read_bytes()
    image.write_bytes(bytes(100 * 1024 + 1))
    with pytest.raises(ImageError, match="more than the 102400 bytes"):
        load_image(image, layout, check_vectors=False)


def test_missing_linker_script_falls_back_to_the_named_figures(tmp_path):
    assert board_layout(tmp_path / "none.ld") == FALLBACK_LAYOUT
    assert FALLBACK_LAYOUT.app_size == 500 * 1024


def test_force_skips_only_the_vector_check(tmp_path):
    path = tmp_path / "raw.bin"
    path.write_bytes(b"\x00\x01\x02")
    with pytest.raises(ImageError, match="too short"):
        load_image(path)
    assert load_image(path, check_vectors=False) == b"\x00\x01\x02"


def test_checksum_is_the_low_byte_of_the_sum():
    assert checksum(b"") == 0
    assert checksum(bytes([0xFF, 0x02])) == 0x01
    assert checksum(bytes(range(256))) == (255 * 256 // 2) & 0xFF


def test_verify_checksum_accepts_either_documented_reading_and_nothing_else():
    image = bytes([0x10, 0x20, 0x30])  # sum 0x60
    sent = image + bytes([0x60])  # sum 0xC0
    assert "every byte" in verify_checksum(image, sent, ChecksumReport(0xC0, 2, b"")).meaning
    assert "without" in verify_checksum(image, sent, ChecksumReport(0x60, 2, b"")).meaning
    with pytest.raises(FlashError, match="reports 0xC1, we expected 0xC0"):
        verify_checksum(image, sent, ChecksumReport(0xC1, 2, b""))
    # Without the trailer only one reading exists.
    with pytest.raises(FlashError):
        verify_checksum(image, image, ChecksumReport(0xC0, 2, b""))
    # A wider report compares the wider sum.
    big = bytes([0xFF] * 3)
    assert verify_checksum(big, big, ChecksumReport(0x2FD, 4, b"")).value == 0x2FD


def test_timeouts_from_environment_and_keywords(monkeypatch):
    monkeypatch.setenv("SNAKEBOT_FLASH_READY_TIMEOUT_S", "7.5")
    timeouts = FlashTimeouts.resolve(reset=2.0)
    assert timeouts.ready == 7.5 and timeouts.reset == 2.0
    assert timeouts.checksum_wait(4097) == pytest.approx(timeouts.checksum + 3 * timeouts.page_time)
    monkeypatch.setenv("SNAKEBOT_FLASH_READY_TIMEOUT_S", "-1")
    with pytest.raises(FlashSettingError, match="SNAKEBOT_FLASH_READY_TIMEOUT_S='-1'"):
        FlashTimeouts.resolve()
