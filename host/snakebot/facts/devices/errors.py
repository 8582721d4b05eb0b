"""The devices package's exception."""

from __future__ import annotations

from snakebot.errors import InputError


class DeviceError(InputError):
    """An unknown device or register, a value a register cannot hold, or a broken
    description file; the message says which and what to do."""
