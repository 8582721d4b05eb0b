"""The emulated CM-530's checks catch a firmware built wrong: each mutant below is the real
firmware with one board fact broken (the bus transmit-enable pin, the bus's baud divisor,
the vector-table write), built like `make firmware`, and the cold-boot check that the real
image passes must fail on it."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
from firmware_support import build_firmware
from test_cm530_boot import assert_boots_as_the_cm530_needs

from snakebot.paths import REPO_ROOT
from snakebot.sim.mcu.errors import McuFault

pytest.importorskip("unicorn")
pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

MUTANTS = {
    "wrong-pin": (
        "boards/cm530/cm530_io.h",
        "#define BOARD_BUS_TX_ENABLE_PIN {HAL_GPIOB_BASE, 4}",
        "#define BOARD_BUS_TX_ENABLE_PIN {HAL_GPIOB_BASE, 8}",
    ),
    "wrong-divisor": (
        "boards/cm530/cm530_io.h",
        "#define BOARD_BUS_BAUD 1000000UL",
        "#define BOARD_BUS_BAUD 500000UL",
    ),
    "no-vtor-write": (
        "hal/hal_startup.c",
        "    hal_set_vector_table((uint32_t)(uintptr_t)hal_vector_table);\n",
        "",
    ),
}


def build_mutant(tmp: Path, name: str) -> bytes:
    """The CM-530 image with the mutant's edit, built by `make` as after editing a
    checkout: beside a copy of the checkout's up-to-date build (sources and objects
    keep their times, and the objects' recorded header dependencies name the build
    directory as `../build`, as here), so that only what the edit touches is rebuilt."""
    if shutil.which("arm-none-eabi-gcc") is None:
        pytest.skip("arm-none-eabi-gcc is not installed: make setup")
    build_firmware()
    src, build = tmp / "firmware", tmp / "build"
    shutil.copytree(REPO_ROOT / "firmware", src)
    for part in ("core", "cm530"):
        shutil.copytree(REPO_ROOT / "build" / part, build / part)
    path, old, new = MUTANTS[name]
    text = (src / path).read_text()
    assert old in text, f"{path} no longer has {old!r}: update the mutant"
    (src / path).write_text(text.replace(old, new))
    done = subprocess.run(
        ["make", "-C", str(src), "cm530"], check=True, capture_output=True, text=True
    )
    image = (build / "cm530" / "firmware.bin").read_bytes()
    # the edit was compiled in (else the check below would judge the real image)
    assert image != (REPO_ROOT / "build" / "cm530" / "firmware.bin").read_bytes(), done.stdout
    return image


@pytest.mark.parametrize("name", sorted(MUTANTS))
def test_a_broken_build_fails_the_boot_check(tmp_path, name):
    image = build_mutant(tmp_path, name)
    with pytest.raises((AssertionError, McuFault)):
        assert_boots_as_the_cm530_needs(image)
