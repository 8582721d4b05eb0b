"""The root of snakebot's exceptions. Each area derives its own from ``SnakebotError``
so the CLI can report any of them in one line (``snakebot.cli.errors``)."""

from __future__ import annotations


class SnakebotError(Exception):
    """A problem the user can act on; its message names the problem and the fix."""
