"""The generated C (firmware/core/kin_gen.[ch]) is what the sympy models give today, and
the kinematic core cross-compiles for the Cortex-M3 under -Werror."""

import re
import shutil
import subprocess

import pytest
import sympy

from snakebot.model.symbolic.codegen import CORE_DIR, generate


def test_regenerating_gives_the_committed_files():
    committed = (CORE_DIR / "kin_gen.c").read_text()
    stamp = re.search(r"sympy (\S+)\.\n", committed)
    assert stamp, "kin_gen.c lacks its sympy version stamp"
    if stamp.group(1) != sympy.__version__:
        pytest.skip(
            f"kin_gen.c was generated with sympy {stamp.group(1)}, installed is "
            f"{sympy.__version__}: its output may differ in form (the values are "
            "checked in test_kin_fields.py)"
        )
    for name, text in generate().items():
        assert (CORE_DIR / name).read_text() == text, (
            f"{name} is stale: run python -m snakebot.model.symbolic.codegen"
        )


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="no arm-none-eabi-gcc")
def test_kinematic_core_cross_compiles_for_cortex_m3(tmp_path):
    for source in sorted(CORE_DIR.glob("kin_*.c")):
        result = subprocess.run(
            [
                "arm-none-eabi-gcc",
                "-mcpu=cortex-m3",
                "-mthumb",
                "-Os",
                "-std=c99",
                "-Wall",
                "-Wextra",
                "-Werror",
                "-ffreestanding",
                "-fno-common",
                f"-I{CORE_DIR}",
                "-c",
                str(source),
                "-o",
                str(tmp_path / (source.stem + ".o")),
            ],
            capture_output=True,
            text=True,
            check=False,
        )
        assert result.returncode == 0, f"{source.name}:\n{result.stderr}"
