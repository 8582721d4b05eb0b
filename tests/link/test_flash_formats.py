"""`snakebot flash` takes the build's .bin, .hex and .elf alike: the three turn into the
same image bytes at the application base (the .elf's loadable segments at their load
addresses), and a damaged file or one that places bytes outside the application area is
refused in one line, before the port is touched."""

from __future__ import annotations

import io
import shutil

import pytest
from click.testing import CliRunner
from firmware_support import CM530_DIR, QEMU_DIR, build_firmware
from flash_support import make_image, serve
from intelhex import IntelHex

from snakebot.cli import main
from snakebot.link.flash import load_image
from snakebot.sim.bootloader import APP_BASE, Bootloader

pytestmark = pytest.mark.timeout(60)

NO_PORT = "/dev/ttySNAKEBOT-missing"


@pytest.fixture(scope="module")
def built():
    build_firmware()
    return CM530_DIR


def hex_of(data: bytes, base: int) -> str:
    ih = IntelHex()
    ih.frombytes(data, offset=base)
    out = io.StringIO()
    ih.write_hex_file(out)
    return out.getvalue()


def test_the_builds_elf_and_hex_load_as_its_bin(built, tmp_path):
    raw = (built / "firmware.bin").read_bytes()
    assert load_image(built / "firmware.elf") == raw
    assert load_image(built / "firmware.hex") == raw
    # A .hex made from the .bin by another tool, under a name that does not say so.
    (tmp_path / "made").write_text(hex_of(raw, APP_BASE))
    assert load_image(tmp_path / "made") == raw


def test_the_elf_flashes_the_same_bytes_as_the_bin(built, monkeypatch):
    monkeypatch.setenv("SNAKEBOT_FLASH_QUIET_S", "0.05")
    monkeypatch.setenv("SNAKEBOT_FLASH_GO_TIMEOUT_S", "0.2")
    raw = (built / "firmware.bin").read_bytes()
    boot = Bootloader(silence_s=0.3)
    with serve(boot) as server:
        result = CliRunner().invoke(
            main, ["flash", "--no-verify", str(built / "firmware.elf"), "--port", server.device]
        )
        with server.lock:
            stored = boot.image
    assert result.exit_code == 0, result.output
    assert stored == raw + bytes([sum(raw) & 0xFF])


def test_gaps_between_segments_are_zero_filled(tmp_path):
    image = make_image(tmp_path / "fw.bin", 600)
    ih = IntelHex()
    ih.frombytes(image[:200], offset=APP_BASE)
    ih.frombytes(image[300:], offset=APP_BASE + 300)
    ih.write_hex_file(str(tmp_path / "gap.hex"))
    loaded = load_image(tmp_path / "gap.hex", check_vectors=False)
    assert loaded == image[:200] + bytes(100) + image[300:]


def bad(tmp_path, name: str, content: bytes | str):
    path = tmp_path / name
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    return CliRunner().invoke(main, ["flash", str(path), "--port", NO_PORT])


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("low.hex", hex_of(b"\x00" * 64, 0x08000000), "outside the CM-530's application area"),
        ("late.hex", hex_of(b"\x00" * 64, APP_BASE + 0x100), "not at the application base"),
        ("past.hex", hex_of(b"\x00" * 16, 0x08080000 - 8), "outside the CM-530's"),
        ("sum.hex", ":0400000001020304F0\n:00000001FF\n", "not a valid Intel HEX file"),
        ("junk.hex", ":zz\n", "not a valid Intel HEX file"),
        ("named.elf", b"\x00" * 64, "named like an ELF file but does not start like one"),
        ("cut.elf", b"\x7fELF\x01\x01\x01" + bytes(40), "not a readable ELF file"),
    ],
)
def test_bad_files_are_refused_in_one_line(tmp_path, name, content, message):
    result = bad(tmp_path, name, content)
    assert result.exit_code == 2, result.output
    assert message in result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.output


def test_an_elf_for_another_machine_or_address_is_refused(built, tmp_path):
    host_elf = shutil.which("true")
    result = bad(tmp_path, "host.elf", open(host_elf, "rb").read())
    assert result.exit_code == 2 and "not for an Arm Cortex-M" in result.stderr
    stub = (QEMU_DIR / "stub.elf").read_bytes()  # linked at 0x08000000: the bootloader's place
    result = bad(tmp_path, "stub.elf", stub)
    assert result.exit_code == 2 and "outside the CM-530's application area" in result.stderr
    qemu = (QEMU_DIR / "firmware.elf").read_bytes()  # the right address, another board
    result = bad(tmp_path, "qemu.elf", qemu)
    assert result.exit_code == 2 and "built for board 'qemu'" in result.stderr


def test_a_truncated_elf_is_refused(built, tmp_path):
    elf = (built / "firmware.elf").read_bytes()
    result = bad(tmp_path, "short.elf", elf[: len(elf) // 3])
    assert result.exit_code == 2, result.output
    assert "is cut short" in result.stderr or "not a readable ELF file" in result.stderr
