"""The upload's named knobs: each has a default and an environment variable that
overrides it; a keyword argument overrides both.

=================================  ==========================  ===========================
setting                            environment variable        default
=================================  ==========================  ===========================
whole-table resends after a loss   SNAKEBOT_UPLOAD_RETRIES     ``DEFAULT_UPLOAD_RETRIES``
WRITEs in flight at once           SNAKEBOT_UPLOAD_WINDOW      ``DEFAULT_UPLOAD_WINDOW``
=================================  ==========================  ===========================

Single READs and WRITEs (status, commands, the roster) retry as every transaction does
(``SNAKEBOT_RETRIES``, :mod:`snakebot.link.transport.settings`).
"""

from __future__ import annotations

import os

from snakebot.link.controller.errors import ControllerInputError

DEFAULT_UPLOAD_RETRIES = 3
"""How often a table whose WRITEs were not all acknowledged (or whose commit found the
staged bytes damaged) is sent again, after the first attempt."""

MAX_UPLOAD_RETRIES = 50

DEFAULT_UPLOAD_WINDOW = 8
"""WRITE packets sent before the first of them must be acknowledged: 8 chunks are about
100 ms of wire at 57600 baud, more than a USB-serial adapter's round trip, so the wire
never idles. 1 makes the upload stop-and-wait."""

MAX_UPLOAD_WINDOW = 64

ENV_UPLOAD_RETRIES = "SNAKEBOT_UPLOAD_RETRIES"
ENV_UPLOAD_WINDOW = "SNAKEBOT_UPLOAD_WINDOW"


def _resolve(value: int | None, env: str, default: int, low: int, high: int, what: str) -> int:
    if value is not None:
        if not isinstance(value, int) or not low <= value <= high:
            raise ControllerInputError(
                f"{what} must be a whole number {low}..{high}, got {value!r}"
            )
        return value
    text = os.environ.get(env, "").strip()
    if not text:
        return default
    try:
        number = int(text)
    except ValueError:
        number = low - 1
    if not low <= number <= high:
        raise ControllerInputError(
            f"{env}={text!r} is not a whole number {low}..{high}; set it to e.g. {default} "
            "or unset it"
        )
    return number


def resolve_upload_retries(value: int | None = None) -> int:
    """Whole-table resends: keyword, else ``SNAKEBOT_UPLOAD_RETRIES``, else the default."""
    return _resolve(
        value, ENV_UPLOAD_RETRIES, DEFAULT_UPLOAD_RETRIES, 0, MAX_UPLOAD_RETRIES, "upload retries"
    )


def resolve_upload_window(value: int | None = None) -> int:
    """WRITEs in flight: keyword, else ``SNAKEBOT_UPLOAD_WINDOW``, else the default."""
    return _resolve(
        value, ENV_UPLOAD_WINDOW, DEFAULT_UPLOAD_WINDOW, 1, MAX_UPLOAD_WINDOW, "upload window"
    )
