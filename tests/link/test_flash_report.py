"""The bootloader's ``Checksum`` report in every plausible format: parsed into its possible
readings, compared with our sums by the width it gives, and, when it reads as no number,
put to the user instead of refused. End to end against the emulated bootloader printing
each format on a real pty."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner
from flash_support import make_image, serve

from snakebot.cli import main
from snakebot.link.flash import parse_report
from snakebot.link.flash.report import Reading
from snakebot.sim.bootloader import APP_BASE, CHECKSUM_FORMATS, Bootloader

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(autouse=True)
def quick_waits(monkeypatch):
    monkeypatch.setenv("SNAKEBOT_FLASH_QUIET_S", "0.05")
    monkeypatch.setenv("SNAKEBOT_FLASH_GO_TIMEOUT_S", "0.2")


@pytest.mark.parametrize(
    ("text", "readings"),
    [
        (": 1A", [(0x1A, 8, 16)]),
        (":1a", [(0x1A, 8, 16)]),
        (": 0x1a2b", [(0x1A2B, 16, 16)]),
        ("  :  0X  00C0FFEE", [(0xC0FFEE, 32, 16)]),
        (": 1A2B3", [(0x1A2B3, 32, 16)]),  # unpadded: the narrowest width that holds it
        (" : 12", [(0x12, 8, 16), (12, 8, 10)]),  # digits alone: either base
        (": 300", [(0x300, 16, 16), (300, 16, 10)]),
        (": 00001234", [(0x1234, 32, 16), (1234, 16, 10)]),
        (" 4294967295", [(4294967295, 32, 10)]),  # ten digits: only decimal fits 32 bits
        (": 0000000000FF", [(0xFF, 8, 16)]),  # zeros padded past 32 bits are padding
        (": 7F (ok)", [(0x7F, 8, 16)]),
        (": OK", []),
        (":", []),
        (": 1A2Bh", []),  # a suffix makes it another format
        (": 01FD", [(0x1FD, 16, 16)]),
        (": 123456789012", []),  # wider than 32 bits either way
    ],
)
def test_report_readings(text, readings):
    assert parse_report(text) == tuple(Reading(*r) for r in readings)


def flash(image_path, boot: Bootloader, *args: str, input: str | None = None):
    with serve(boot) as server:
        result = CliRunner().invoke(
            main,
            ["flash", "--no-verify", str(image_path), "--port", server.device, *args],
            input=input,
        )
        with server.lock:
            started = list(boot.started)
    return result, started


@pytest.mark.parametrize("fmt", [f for f in CHECKSUM_FORMATS if f != "unknown"])
@pytest.mark.parametrize("excludes_last", [False, True], ids=["all", "image"])
def test_every_known_format_verifies_the_upload(tmp_path, fmt, excludes_last):
    image = make_image(tmp_path / "fw.bin", 3000, seed=5)
    boot = Bootloader(silence_s=0.3, checksum_format=fmt, sum_excludes_last=excludes_last)
    result, started = flash(tmp_path / "fw.bin", boot, "--json")
    assert result.exit_code == 0, result.output
    bits = CHECKSUM_FORMATS[fmt][1]
    summed = image if excludes_last else image + bytes([sum(image) & 0xFF])
    assert json.loads(result.stdout)["checksum"] == sum(summed) % (1 << bits)
    assert started == [APP_BASE]


def test_unknown_format_without_yes_and_nobody_to_ask_stops_before_go(tmp_path):
    make_image(tmp_path / "fw.bin", 1000, seed=7)
    result, started = flash(tmp_path / "fw.bin", Bootloader(checksum_format="unknown"))
    assert result.exit_code == 1
    assert "warning: the bootloader's report 'Checksum: OK' is in a format" in result.stdout
    assert "run again with --yes" in result.stderr
    assert "press MODE or power-cycle the CM-530" in result.stderr
    assert started == []


def test_unknown_format_with_yes_starts_unverified(tmp_path):
    make_image(tmp_path / "fw.bin", 1000, seed=7)
    boot = Bootloader(checksum_format="unknown")
    result, started = flash(tmp_path / "fw.bin", boot, "--yes", "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["checksum"] is None and report["checksum_meaning"].startswith("unverified")
    assert "Checksum NOT verified" in result.stderr
    assert started == [APP_BASE]


@pytest.mark.parametrize(("answer", "code", "go"), [("y\n", 0, True), ("n\n", 1, False)])
def test_unknown_format_asks_at_a_terminal(tmp_path, monkeypatch, answer, code, go):
    monkeypatch.setattr("snakebot.cli.flash._interactive", lambda: True)
    make_image(tmp_path / "fw.bin", 1000, seed=7)
    result, started = flash(
        tmp_path / "fw.bin", Bootloader(checksum_format="unknown"), input=answer
    )
    assert "Start the new firmware anyway?" in result.output
    assert result.exit_code == code, result.output
    assert started == ([APP_BASE] if go else [])
