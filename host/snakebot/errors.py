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

A message stays one short line however long the input it is about: a value quoted back
goes through :func:`quoted` (its start and end around ``...`` and its length), and the
CLI bounds every error line it prints to :data:`LINE_LIMIT` characters with
:func:`bounded_line`, which also shortens what click and the operating system quote.
"""

from __future__ import annotations

import re
from typing import TypeVar

E = TypeVar("E", bound="SnakebotError")

QUOTE_LIMIT = 160
"""The most characters of a value (a number list, an expression, a name) a message
quotes back; a longer one is shown by its start and end and its length."""
WORD_LIMIT = 200
"""The longest run without spaces an error line keeps whole (a path, a quoted value);
longer ones are shortened like a quoted value."""
LINE_LIMIT = 400
"""The longest error line the CLI prints, ``error: `` and the help hint included."""
_LONG_WORD = re.compile(rf"\S{{{WORD_LIMIT + 1},}}")


def _ends(text: str, limit: int) -> str:
    """The start and end of ``text`` around ``...``, room left in ``limit`` for its length."""
    keep = max(limit - 24, 8)
    head = keep * 2 // 3
    return f"{text[:head]}...{text[len(text) - (keep - head) :]}"


def shortened(text: str, limit: int = QUOTE_LIMIT) -> str:
    """``text`` if at most ``limit`` characters, else its start and end around ``...``
    followed by its length: ``0.1,0.1,0.1,...,0.1 (60,000 characters)``, about
    ``limit`` characters in all."""
    return text if len(text) <= limit else f"{_ends(text, limit)} ({len(text):,} characters)"


def quoted(value: object, limit: int = QUOTE_LIMIT) -> str:
    """``value`` quoted back in a message as ``{value!r}`` would (a string in quotes),
    its start and end around ``...`` and its length when longer than ``limit``:
    ``'0.1,0.1,...,0.1' (60,000 characters)``."""
    if not isinstance(value, str):
        return shortened(repr(value), limit)
    if len(value) <= limit:
        return repr(value)
    return f"{_ends(value, limit)!r} ({len(value):,} characters)"


def _shortened_word(match: re.Match[str]) -> str:
    word = match.group()
    body = word.rstrip(":;,.")  # the punctuation after a value stays after its length
    return shortened(body, WORD_LIMIT // 2) + word[len(body) :]


def bounded_line(text: str, limit: int = LINE_LIMIT) -> str:
    """The one-line message ``text`` in at most ``limit`` characters: every run without
    spaces longer than :data:`WORD_LIMIT` shortened (a quoted value, a path), then, if
    still too long, its middle left out (the start says what is wrong, the end the fix)."""
    if len(text) <= limit:
        return text
    length = len(text)
    text = _LONG_WORD.sub(_shortened_word, text)
    if len(text) <= limit:
        return text
    gap = f" ... ({length:,} characters in all) ... "
    keep = max(limit - len(gap), 2)
    head = keep * 2 // 3
    return f"{text[:head].rstrip()}{gap}{text[len(text) - (keep - head) :].lstrip()}"


class SnakebotError(Exception):
    """A problem the user can act on; its message names the problem and the fix."""

    params: tuple[str, ...] = ()
    """The parameters whose values are at fault or are the fix (``rate``), if any."""

    def about(self: E, *params: str) -> E:
        """This error, noting that the values of parameters ``params`` are at fault or
        are the fix; the CLI names its options for them."""
        self.params = params
        return self


class InputError(SnakebotError):
    """Bad input: a value, file, setting or request that cannot be used as it is (exit 2)."""


class RuntimeFailure(SnakebotError):
    """The input was fine, the world did not cooperate: a device, link, process or
    state that got in the way (exit 1)."""
