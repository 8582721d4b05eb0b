"""The root of snakebot's exceptions, and the two kinds every one of them is.

Each area derives its errors from one of two bases, by what the error means:

* ``InputError``: bad input. The command line, a file, a setting or what was asked of
  the robot cannot be used as it is; running again unchanged fails the same way.
  The CLI exits with status 2.
* ``RuntimeFailure``: the input was fine, the world did not cooperate: a device that
  does not answer, damaged bytes on a link, a controller in the safe state, a process
  that died. The CLI exits with status 1.

An area may keep a base of its own that spans both kinds (``ProtocolError``,
``ControllerError``, ...), but nothing raises it directly: every class that is raised is
under exactly one of the two (``tests/test_errors.py`` walks the package to check).
The CLI's exit status follows the class (``snakebot.cli.errors``), never a list.

Messages name the problem and the fix in the library's words. When the value came
through a parameter, ``about(name)`` records the parameter's name (the name the CLI's
parameter has too: ``rate``, ``robot``): the CLI then names the option it came from
(``--rate``), so library messages never spell a command-line option.
"""

from __future__ import annotations

from typing import Self


class SnakebotError(Exception):
    """A problem the user can act on; its message names the problem and the fix."""

    params: tuple[str, ...] = ()
    """The parameters whose values are at fault or are the fix (``rate``), if any."""

    def about(self, *params: str) -> Self:
        """This error, noting that the values of parameters ``params`` are at fault or
        are the fix; the CLI names its options for them."""
        self.params = params
        return self


class InputError(SnakebotError):
    """Bad input: a value, file, setting or request that cannot be used as it is (exit 2)."""


class RuntimeFailure(SnakebotError):
    """The input was fine, the world did not cooperate: a device, link, process or
    state that got in the way (exit 1)."""
