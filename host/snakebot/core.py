"""Access to the compiled C core (``snakebot._core``), with a clear error if it is missing."""

from __future__ import annotations

try:
    from snakebot._core import ffi, lib
except ImportError as exc:  # pragma: no cover - only on a broken install
    raise ImportError(
        "snakebot's C core (snakebot._core) is not built: run `make setup` "
        "(or `pip install -e .`) from the repository root"
    ) from exc

__all__ = ["ffi", "lib"]
