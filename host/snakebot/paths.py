"""Where the repository's shared, non-Python files live, for tests and generators.

``protocol/`` (packet vectors, the gait-table layout) and ``firmware/`` sit at the
repository root so the C and Python sides read the same files. They are not installed:
what the package needs at run time ships inside it (package data: the control tables in
:mod:`snakebot.facts.devices`, the firmware images through :mod:`snakebot.firmware`). These
helpers serve code that runs from a checkout (an editable install): the tests, the code
generators, the development harnesses. ``SNAKEBOT_PROTOCOL_DIR`` overrides the protocol
directory (read through :mod:`snakebot.settings`: a path that is not a directory is
refused there, with the variable's name).
"""

from __future__ import annotations

from pathlib import Path

from snakebot.settings import lookup_path

REPO_ROOT = Path(__file__).resolve().parents[2]
"""The checkout's root when snakebot is installed editable; meaningless otherwise (an
installed package's parents are site-packages), so ask :func:`in_checkout` first."""


def in_checkout() -> bool:
    """Whether this snakebot runs from its repository (an editable install)."""
    return (REPO_ROOT / "firmware" / "Makefile").is_file() and (
        REPO_ROOT / "host" / "snakebot"
    ).is_dir()


def protocol_dir() -> Path:
    """The repository's ``protocol/`` directory (``vectors/``, the layout documents)."""
    override = lookup_path("SNAKEBOT_PROTOCOL_DIR")
    if override is not None:
        return override
    path = REPO_ROOT / "protocol"
    if not path.is_dir():
        raise FileNotFoundError(
            f"protocol data not found at {path}: it is part of the snakebot repository; "
            "run this from a checkout (make setup) or set SNAKEBOT_PROTOCOL_DIR"
        )
    return path
