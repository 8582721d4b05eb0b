"""Errors of the host's controller operations (upload, playback, monitor). Each message
says what went wrong and what to do about it; the CLI prints it as ``error: ...``.

``ControllerError`` (and ``UploadError``, ``LibraryError`` beside it) are area bases:
what is raised is one of the concrete classes, each bad input (exit 2) or a runtime
failure (exit 1) by ``snakebot.errors``. A refusal by the controller is classed by its
reason (``snakebot.link.controller.messages.RUNTIME_RESULTS``), so the same refusal
exits the same way from every command.
"""

from __future__ import annotations

from snakebot.errors import InputError, RuntimeFailure, SnakebotError


class ControllerError(SnakebotError):
    """The controller refused something, or is not in a state to do it (the area's base)."""


class ControllerInputError(ControllerError, InputError):
    """What was asked of the controller cannot be done as asked: a value outside what it
    takes, a table it cannot hold, an empty roster, no table to play."""


class ControllerStateError(ControllerError, RuntimeFailure):
    """The request was fine but the controller is not in a state to do it: the safe
    state, servos that do not yet hold the robot's limits, a command that did not start."""


class ControllerRefused(ControllerError, InputError):
    """The controller answered with an error byte (``flags``): it refused the instruction
    and changed nothing."""

    def __init__(self, message: str, flags: int) -> None:
        super().__init__(message)
        self.flags = flags


class ControllerLinkError(ControllerError, RuntimeFailure):
    """The controller did not answer on the PC link, or answered with damaged packets.
    ``problem`` is what happened, without the hint that follows it in the message (a
    caller that knows better, such as the demo with its emulated controller, gives its
    own)."""

    def __init__(self, problem: str, hint: str) -> None:
        super().__init__(f"{problem}: {hint}")
        self.problem = problem


class NotAController(ControllerError, InputError):
    """The device at the controller's ID is not a snakebot controller (or speaks another
    version of its control table)."""


class UploadError(ControllerError):
    """A gait table was not made active (the base of the two below). ``old_table_active``
    tells whether the controller's previous table is known to be still in place."""

    def __init__(self, message: str, *, old_table_active: bool = True) -> None:
        super().__init__(message)
        self.old_table_active = old_table_active


class UploadRefused(UploadError, InputError):
    """The table cannot be made active on this controller as it is: too many joints,
    servos the roster lacks, a table outside the robot's limits."""


class UploadFailed(UploadError, RuntimeFailure):
    """The upload did not land: chunks lost or damaged, the controller stopped answering
    or was busy."""


class LibraryError(ControllerError):
    """A gait-library operation that did not happen (the base of the two below)."""


class LibraryRefused(LibraryError, InputError):
    """The controller refused a library operation for what was asked: no such slot, a bad
    name, an empty slot, a table outside the robot's limits."""


class LibraryFailed(LibraryError, RuntimeFailure):
    """A library operation the controller could not carry out: a flash write that does
    not end or fails, a slot read back damaged, a slot that did not play."""
