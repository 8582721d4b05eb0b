"""Errors of the host's controller operations (upload, playback, monitor). Each message
says what went wrong and what to do about it; the CLI prints it as ``error: ...``."""

from __future__ import annotations

from snakebot.errors import SnakebotError


class ControllerError(SnakebotError):
    """The controller refused something, or is not in a state to do it."""


class ControllerRefused(ControllerError):
    """The controller answered with an error byte (``flags``): it refused the instruction
    and changed nothing."""

    def __init__(self, message: str, flags: int) -> None:
        super().__init__(message)
        self.flags = flags


class ControllerLinkError(ControllerError):
    """The controller did not answer on the PC link, or answered with damaged packets."""


class NotAController(ControllerError):
    """The device at the controller's ID is not a snakebot controller (or speaks another
    version of its control table)."""


class UploadError(ControllerError):
    """A gait table was not made active. ``old_table_active`` tells whether the
    controller's previous table is known to be still in place."""

    def __init__(self, message: str, *, old_table_active: bool = True) -> None:
        super().__init__(message)
        self.old_table_active = old_table_active
