"""Reading the CM-530's memory layout from its linker script, and the image checks."""

from __future__ import annotations

import pytest

from snakebot.link.flash import FlashTimeouts, ImageError, board_layout, checksum, load_image
from snakebot.link.flash.bootloader import ChecksumReport, verify_checksum
from snakebot.link.flash.errors import FlashError
from snakebot.link.flash.image import FALLBACK_LAYOUT, identity_block
from snakebot.settings import SettingError


def vectors(sp: int, reset: int, base: int, size: int, board: str = "cm530") -> bytes:
    """An image of ``size`` bytes at ``base``: eight vectors (SP, reset, entry 7 pointing
    at the identity block right after them), the block, then zeros."""
    words = [sp, reset, 0, 0, 0, 0, 0, base + 32]
    head = b"".join(w.to_bytes(4, "little") for w in words) + identity_block(board, 1, size)
    return head + bytes(size - len(head))


def test_layout_comes_from_the_cm530_linker_script():
    layout = board_layout()
    assert layout.source.endswith("firmware/boards/cm530/cm530.ld")
    assert layout.app_base == 0x08003000
    assert layout.flash_end == 0x08080000  # the stores and a free region run to the end
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
    image.write_bytes(vectors(0x20005000, 0x08004041, 0x08004000, 100))
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
    assert "every byte" in verify_checksum(image, sent, ChecksumReport(": C0", b"")).meaning
    assert "without" in verify_checksum(image, sent, ChecksumReport(": 60", b"")).meaning
    with pytest.raises(FlashError, match=r"reports 'Checksum: C1', we expected 0xC0"):
        verify_checksum(image, sent, ChecksumReport(": C1", b""))
    # Without the trailer only one reading exists.
    with pytest.raises(FlashError):
        verify_checksum(image, image, ChecksumReport(": C0", b""))
    # A wider report compares the wider sum.
    big = bytes([0xFF] * 3)
    assert verify_checksum(big, big, ChecksumReport(": 02FD", b"")).value == 0x2FD
    with pytest.raises(FlashError):
        verify_checksum(big, big, ChecksumReport(": 01FD", b""))


def test_timeouts_from_environment_and_keywords(monkeypatch):
    monkeypatch.setenv("SNAKEBOT_FLASH_READY_TIMEOUT_S", "7.5")
    timeouts = FlashTimeouts.resolve(reset=2.0)
    assert timeouts.ready == 7.5 and timeouts.reset == 2.0
    assert timeouts.checksum_wait(4097) == pytest.approx(timeouts.checksum + 3 * timeouts.page_time)
    monkeypatch.setenv("SNAKEBOT_FLASH_READY_TIMEOUT_S", "-1")
    with pytest.raises(SettingError, match="SNAKEBOT_FLASH_READY_TIMEOUT_S='-1'"):
        FlashTimeouts.resolve()


@pytest.mark.parametrize(
    ("sp", "reset", "board", "size", "says", "message"),
    [
        (0x2000FFFF, 0x08003101, "cm530", 512, 512, "not 8-byte aligned"),
        (0x2000FFFC, 0x08003101, "cm530", 512, 512, "not 8-byte aligned"),
        (0x20010008, 0x08003101, "cm530", 512, 512, "outside the CM-530's RAM"),
        (0x20010000, 0x08003009, "cm530", 512, 512, "inside its vector table or identity"),
        (0x20010000, 0x08003031, "cm530", 512, 512, "inside its vector table or identity"),
        (0x20010000, 0x08003201, "cm530", 512, 512, "not a Thumb address inside the image"),
        (0x20010000, 0x08003100, "cm530", 512, 512, "not a Thumb address"),
        (0x20010000, 0x08003101, "qemu", 512, 512, "built for board 'qemu', not 'cm530'"),
        (0x20010000, 0x08003101, "cm530", 512, 600, "is 512 bytes but says it is 600"),
    ],
)
def test_images_the_cm530_would_not_start_are_refused(
    tmp_path, sp, reset, board, size, says, message
):
    path = tmp_path / "fw.bin"
    data = bytearray(vectors(sp, reset, 0x08003000, size, board))
    data[32 + 8 : 32 + 12] = says.to_bytes(4, "little")
    path.write_bytes(bytes(data))
    with pytest.raises(ImageError, match=message):
        load_image(path)
    assert load_image(path, check_vectors=False) == bytes(data)  # --force


def test_an_image_without_an_identity_block_is_refused(tmp_path):
    path = tmp_path / "fw.bin"
    words = [0x20010000, 0x08003041] + [0] * 6
    path.write_bytes(b"".join(w.to_bytes(4, "little") for w in words) + bytes(200))
    with pytest.raises(ImageError, match="no snakebot identity block"):
        load_image(path)


def test_the_built_images_carry_their_board_and_length():
    """Both builds link at 0x08003000 with a stack in the CM-530's RAM: only the identity
    block tells the qemu image from the CM-530's, and the flasher refuses it."""
    from firmware_support import build_firmware

    from snakebot.link.flash.image import BOARD_LINKER_SCRIPT, image_info
    from snakebot.paths import REPO_ROOT

    build_firmware()
    version = int(
        next(
            line.split()[2]
            for line in (REPO_ROOT / "firmware/core/ctl_table.h").read_text().splitlines()
            if line.startswith("#define CTL_FIRMWARE_VERSION_VALUE")
        )
    )
    for board in ("cm530", "qemu"):
        data = (REPO_ROOT / "build" / board / "firmware.bin").read_bytes()
        info = image_info(data, board_layout().app_base)
        assert (info.board, info.image_bytes, info.firmware_version) == (board, len(data), version)
    assert load_image(REPO_ROOT / "build/cm530/firmware.bin")
    with pytest.raises(ImageError, match="built for board 'qemu'"):
        load_image(REPO_ROOT / "build/qemu/firmware.bin")
    assert BOARD_LINKER_SCRIPT.exists()
