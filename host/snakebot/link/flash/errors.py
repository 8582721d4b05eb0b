"""The flasher's errors: each says what went wrong on the way into the bootloader and
what to do about it. ``FlashError`` is the area's base: what is raised is bad input
(``ImageError``, ``FlashSettingError``: exit 2) or a runtime failure (``FlashFailed``:
exit 1)."""

from __future__ import annotations

from snakebot.errors import InputError, RuntimeFailure, SnakebotError


class FlashError(SnakebotError):
    """Flashing through the ROBOTIS bootloader did not happen (the area's base)."""


class FlashFailed(FlashError, RuntimeFailure):
    """Flashing failed on the way; the message names the step and the fix."""


class ImageError(FlashError, InputError):
    """The firmware file cannot be flashed as it is (missing, empty, too big, wrong format)."""


class FlashSettingError(FlashError, InputError, ValueError):
    """A flasher timeout set in the environment is not a usable number."""
