"""Errors of the serial transport that are not about packets (those live in
``snakebot.formats.protocol.errors``): a port that cannot be opened, a setting that makes
no sense."""

from __future__ import annotations

from snakebot.errors import InputError


class PortError(InputError):
    """The serial port could not be opened; the message names the port and the fix."""

    def __init__(self, port: str, message: str) -> None:
        super().__init__(message)
        self.port = port


class TransportSettingError(InputError, ValueError):
    """A transport setting (keyword or environment variable) has an unusable value."""
