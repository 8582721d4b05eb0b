"""The upload's named knobs: each has a default and an environment variable that
overrides it; a keyword argument overrides both.

=================================  ==========================  ===========================
setting                            environment variable        default
=================================  ==========================  ===========================
whole-table resends after a loss   SNAKEBOT_UPLOAD_RETRIES     ``DEFAULT_UPLOAD_RETRIES``
WRITEs in flight at once           SNAKEBOT_UPLOAD_WINDOW      ``DEFAULT_UPLOAD_WINDOW``
=================================  ==========================  ===========================

The variables, their ranges and defaults are rows of the one table in
:mod:`snakebot.settings`, which reads and checks them. Single READs and WRITEs (status,
commands, the roster) retry as every transaction does (``SNAKEBOT_RETRIES``,
:mod:`snakebot.link.transport.settings`).
"""

from __future__ import annotations

from snakebot import settings as table
from snakebot.errors import quoted
from snakebot.link.controller.errors import ControllerInputError

ENV_UPLOAD_RETRIES = "SNAKEBOT_UPLOAD_RETRIES"
ENV_UPLOAD_WINDOW = "SNAKEBOT_UPLOAD_WINDOW"

DEFAULT_UPLOAD_RETRIES = table.default_int(ENV_UPLOAD_RETRIES)
"""How often a table whose WRITEs were not all acknowledged (or whose commit found the
staged bytes damaged) is sent again, after the first attempt."""

MAX_UPLOAD_RETRIES = int(table.setting(ENV_UPLOAD_RETRIES).high or 0)

DEFAULT_UPLOAD_WINDOW = table.default_int(ENV_UPLOAD_WINDOW)
"""WRITE packets sent before the first of them must be acknowledged: 8 chunks are about
100 ms of wire at 57600 baud, more than a USB-serial adapter's round trip, so the wire
never idles. 1 makes the upload stop-and-wait."""

MAX_UPLOAD_WINDOW = int(table.setting(ENV_UPLOAD_WINDOW).high or 0)


def _resolve(value: int | None, env: str, what: str) -> int:
    if value is None:
        return table.resolve_int(env)
    row = table.setting(env)
    low, high = int(row.low or 0), int(row.high or 0)
    if not isinstance(value, int) or not low <= value <= high:
        raise ControllerInputError(
            f"{what} must be a whole number {low}..{high}, got {quoted(value)}"
        )
    return value


def resolve_upload_retries(value: int | None = None) -> int:
    """Whole-table resends: keyword, else ``SNAKEBOT_UPLOAD_RETRIES``, else the default."""
    return _resolve(value, ENV_UPLOAD_RETRIES, "upload retries")


def resolve_upload_window(value: int | None = None) -> int:
    """WRITEs in flight: keyword, else ``SNAKEBOT_UPLOAD_WINDOW``, else the default."""
    return _resolve(value, ENV_UPLOAD_WINDOW, "upload window")
