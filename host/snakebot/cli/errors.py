"""One place where errors become a one-line message and exit status 2.

Library errors (``SnakebotError``) and operating-system errors (a missing port, a file
that cannot be written; pyserial's ``SerialException`` is an ``OSError``) are expected
failures: the user gets a sentence, not a traceback.
"""

from __future__ import annotations

from typing import Any

import click

from snakebot.errors import SnakebotError

EXIT_FAILURE = 2


class SnakebotGroup(click.Group):
    """A click group that reports expected failures as ``error: ...`` and exits 2."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except (SnakebotError, OSError) as exc:
            click.echo(f"error: {exc}", err=True)
            ctx.exit(EXIT_FAILURE)
