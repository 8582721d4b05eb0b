"""The emulator's errors: each names the problem and the fix."""

from __future__ import annotations

from snakebot.errors import SnakebotError


class SimError(SnakebotError):
    """Something the emulator cannot do as asked."""


class SimOptionError(SimError, ValueError):
    """An emulator option (URL query, command-line flag) that is unknown or out of range."""
