"""The firmware images snakebot runs and flashes: built in this checkout, else shipped.

``make firmware`` writes ``build/<board>/<file>`` in a checkout; a wheel carries the same
files as package data under ``snakebot/firmware/images/<board>/<file>`` (``setup.py``
copies them in), so ``snakebot demo``, ``sim serve`` and ``flash`` work from a plain
``pip install`` with neither a checkout nor a cross-compiler. An image built in the
checkout wins, so a developer always runs what they just compiled.

Part of the package root: every layer may import it; it imports only ``paths``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from snakebot.paths import REPO_ROOT, in_checkout

SHIPPED = (
    ("cm530", "firmware.bin"),
    ("qemu", "firmware.elf"),
    ("qemu", "stub.elf"),
    ("qemu", "flash.bin"),
)
"""What the wheel carries, as (board, file) under ``build/`` and ``images/``: the CM-530
application for ``flash``, and for QEMU the application ELF with the boot stub that goes
in front of it, and the whole-flash image the two make."""

BUILD_DIR = REPO_ROOT / "build"


def built_image(board: str, name: str) -> Path:
    """Where ``make firmware`` puts ``name`` for ``board`` in this checkout."""
    return BUILD_DIR / board / name


def shipped_image(board: str, name: str) -> Path:
    """Where the installed package keeps its copy of ``name`` for ``board``."""
    return Path(str(resources.files(__name__).joinpath("images", board, name)))


def image(board: str, name: str) -> Path:
    """The image to use: the checkout's build if it exists, else the shipped copy.

    When neither exists the checkout's path is returned inside a checkout (so the error
    a caller raises says ``make firmware``), the shipped path otherwise."""
    built = built_image(board, name)
    if in_checkout() and built.is_file():
        return built
    shipped = shipped_image(board, name)
    if shipped.is_file() or not in_checkout():
        return shipped
    return built
