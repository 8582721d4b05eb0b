"""Where the project's shared, non-Python files live.

``protocol/`` holds the facts that cross a wire (packet vectors, the gait-table layout;
the control tables are package data in ``snakebot.devices``). It sits at the repository
root so the C and Python sides read the same files; snakebot is installed editable
(``make setup``) and finds it from here.
The environment variable ``SNAKEBOT_PROTOCOL_DIR`` overrides the location.
"""

from __future__ import annotations

import os
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]


def protocol_dir() -> Path:
    """The directory holding ``vectors/`` and the layout documents."""
    override = os.environ.get("SNAKEBOT_PROTOCOL_DIR")
    path = Path(override) if override else REPO_ROOT / "protocol"
    if not path.is_dir():
        raise FileNotFoundError(
            f"protocol data not found at {path}: install snakebot editable from its "
            "repository (make setup) or set SNAKEBOT_PROTOCOL_DIR"
        )
    return path
