"""The emulator's errors: each names the problem and the fix. ``SimError`` is the area's
base: what is raised is bad input (``SimInputError``: exit 2) or a runtime failure
(``SimFailure``: exit 1)."""

from __future__ import annotations

from snakebot.errors import InputError, RuntimeFailure, SnakebotError


class SimError(SnakebotError):
    """Something the emulator cannot do as asked (the area's base)."""


class SimInputError(SimError, InputError):
    """A file, path or request the emulator cannot use as it is: a firmware that is not
    an ARM image, a state file of other servos, a link path that is taken."""


class SimOptionError(SimInputError, ValueError):
    """An emulator option (URL query, command-line flag) that is unknown or out of range."""


class SimFailure(SimError, RuntimeFailure):
    """The emulator could not run as asked: QEMU died or did not come up, a socket
    could not be made, the firmware did not answer."""
