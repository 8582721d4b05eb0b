"""Saving a figure the one way outputs are written (``snakebot.userfiles``): checked,
drawn into a temporary file beside the target, then moved over it."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from snakebot.userfiles import staged_output


def save_figure(fig: Any, out: str | os.PathLike[str], dpi: int) -> Path:
    """Save the matplotlib ``fig`` to ``out`` (its format from the extension) atomically;
    ``out`` as a Path."""
    with staged_output(out) as temp:
        fig.savefig(temp, dpi=dpi)
    return Path(out)
