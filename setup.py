"""Build steps pyproject.toml cannot express; all metadata is in pyproject.toml.

- ``snakebot._core``: the portable C core compiled by cffi (``cffi_modules``) against the
  stable ABI, so one ``cp310-abi3`` wheel serves CPython 3.10 and every later version.
- Firmware images inside the wheel (``snakebot/firmware/images/<board>/<file>``, the list
  is ``snakebot.firmware.SHIPPED``): taken from the sdist when it carries them (so a wheel
  built from the sdist needs no cross-compiler), else built with ``make -C firmware``.
  The sdist gets the same images, built the same way. Images are never kept in git.
"""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.command.sdist import sdist
from setuptools.errors import SetupError

ROOT = Path(__file__).resolve().parent
BUILD = ROOT / "build"
IMAGES = Path("snakebot") / "firmware" / "images"
SDIST_IMAGES = ROOT / "host" / IMAGES
CROSS_CC = "arm-none-eabi-gcc"


def _shipped() -> tuple[tuple[str, str], ...]:
    # The list lives in the package; read it without importing snakebot, whose
    # dependencies need not be installed in the build environment.
    module = ast.parse((ROOT / "host" / "snakebot" / "firmware" / "__init__.py").read_text())
    for node in module.body:
        if isinstance(node, ast.Assign) and ast.unparse(node.targets[0]) == "SHIPPED":
            return ast.literal_eval(node.value)
    raise SetupError("snakebot/firmware/__init__.py lost its SHIPPED list")


def _missing(directory: Path) -> list[str]:
    return [f"{b}/{n}" for b, n in _shipped() if not (directory / b / n).is_file()]


def _built_images() -> Path:
    """``build/`` with every shipped image in it: compiled now when the cross-compiler
    is there, else what an earlier ``make firmware`` left."""
    if shutil.which(CROSS_CC) and (ROOT / "firmware" / "Makefile").is_file():
        done = subprocess.run(
            ["make", "-C", str(ROOT / "firmware"), "--no-print-directory", "all"],
            capture_output=True,
            text=True,
            check=False,
        )
        if done.returncode != 0:
            sys.stderr.write(done.stdout + done.stderr)
            raise SetupError("make -C firmware failed (its output is above)")
    missing = _missing(BUILD)
    if missing:
        raise SetupError(
            f"no firmware images to ship ({', '.join(missing)} missing under build/): "
            f"install {CROSS_CC} (make setup) or build from an sdist, which carries them"
        )
    return BUILD


def _copy_images(source: Path, dest: Path) -> None:
    for board, name in _shipped():
        (dest / board).mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source / board / name, dest / board / name)


class BuildPy(build_py):
    """Adds the firmware images to the package; leaves the build script out of it."""

    def find_package_modules(self, package: str, package_dir: str) -> list[tuple[str, str, str]]:
        modules = super().find_package_modules(package, package_dir)
        return [m for m in modules if not (m[0] == "snakebot" and m[1] == "_core_build")]

    def run(self) -> None:
        super().run()
        if self.editable_mode:  # an editable install uses the checkout's build/ directly
            return
        source = SDIST_IMAGES if not _missing(SDIST_IMAGES) else _built_images()
        _copy_images(source, Path(self.build_lib) / IMAGES)


class Sdist(sdist):
    """Puts the firmware images into the sdist, where :class:`BuildPy` finds them."""

    def make_release_tree(self, base_dir: str, files: list[str]) -> None:
        super().make_release_tree(base_dir, files)
        _copy_images(_built_images(), Path(base_dir) / "host" / IMAGES)


setup(
    cffi_modules=["host/snakebot/_core_build.py:ffibuilder"],
    cmdclass={"build_py": BuildPy, "sdist": Sdist},
    options={"bdist_wheel": {"py_limited_api": "cp310"}},
)
