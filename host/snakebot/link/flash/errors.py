"""The flasher's errors: each says what went wrong on the way into the bootloader and
what to do about it."""

from __future__ import annotations

from snakebot.errors import SnakebotError


class FlashError(SnakebotError):
    """Flashing through the ROBOTIS bootloader failed; the message names the step and the fix."""


class ImageError(FlashError):
    """The firmware file cannot be flashed as it is (missing, empty, too big, wrong format)."""


class FlashSettingError(FlashError, ValueError):
    """A flasher timeout set in the environment is not a usable number."""
