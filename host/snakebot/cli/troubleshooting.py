"""The errors ``docs/troubleshooting.md`` explains, each under a short stable code.

The CLI prints the code with the error (``error[E101]: serial port /dev/ttyUSB9 does not
exist: ...``) and the page's heading for it starts with the code
(``### E101 `serial port ... does not exist` ``), so a user goes from the one to the
other by searching for the code. :data:`ENTRIES` is the one list: the page's headings
are checked against it, in order and both ways, and every message in the code that an
entry quotes is checked to print its code (``tests/docs/test_troubleshooting_codes.py``).

A code is never reused for another error: an entry that goes leaves its code unused.
"""

from __future__ import annotations

import re

from snakebot.errors import LINE_LIMIT, bounded_line

PAGE = "docs/troubleshooting.md"
"""The page whose headings carry the codes."""

HOLE = "..."
"""What a quoted message has where the tools fill in a port, servo, file or number."""

ENTRIES: dict[str, str] = {
    # Ports
    "E101": "serial port ... does not exist",
    "E102": "no permission to open serial port ...",
    "E103": "serial port ... is in use by another program",
    "E104": "nothing is listening at ...",
    # Servos that do not answer
    "E201": "no reply to ... within ... ms at ... baud",
    "E202": "no servo answered",
    "E203": "no reply from servo...",
    # The controller
    "E301": "... did not answer ... at ... baud: check that the CM-530 is powered",
    "E302": "the device at ID ... reports model number ..., not a snakebot controller",
    # Flashing
    "E401": "no answer from the CM-530 bootloader on ...",
    "E402": "the board answered '#' but kept sending for more than ...",
    "E403": "the bootloader did not answer the load command",
    "E404": "the port ... does not take data",
    "E405": "the link stopped taking data after ...",
    "E406": "the bootloader sent no 'Checksum:' report within ...",
    "E407": "checksum mismatch: the bootloader reports ...",
    "E408": "the new firmware did not answer PING at ID ... within ...",
    "E409": "the controller runs firmware version ...",
    "E410": "firmware image ... not found",
    # The emulator
    "E501": "qemu-system-arm not found",
    "E502": "QEMU (...) exited at start-up",
    "E503": "QEMU did not come up within ...",
    # Optional packages
    "E601": "... needs ..., which is not installed: ...",
    # Files
    "E701": "... exists already: name a new file, or allow replacing it",
    "E702": "... is a symbolic link (to ...): snakebot never writes through a link",
}
"""Code -> the message as ``docs/troubleshooting.md`` quotes it (``...`` for the parts
the tools fill in), in the page's order."""


def quotes(quoted: str, text: str) -> bool:
    """Whether ``text`` holds the message ``quoted`` with ``...`` for its variable parts
    (any text, even none: a message may be built in pieces). Each part is found after
    the one before (the earliest place is as good as any), in time linear in ``text``
    however long it is: a message may repeat a long input back."""
    at = 0
    for part in quoted.split(HOLE):
        found = text.find(part, at)
        if found < 0:
            return False
        at = found + len(part)
    return True


def code_of(text: str) -> str | None:
    """The code of the entry that explains the error message ``text``, or None."""
    for code, quoted in ENTRIES.items():
        if quotes(quoted, text):
            return code
    return None


ERROR_LINE = re.compile(r"error(?:\[(E\d{3})\])?: ")
"""How every error line the CLI prints starts (group 1: the code, if it has one)."""


def error_line(text: str, hint: str = "") -> str:
    """The line the CLI prints for the one-line error message ``text``: ``error: text``,
    or ``error[E101]: text`` when an entry explains it, then ``hint``; at most
    ``LINE_LIMIT`` characters however long an input ``text`` quotes (``bounded_line``)."""
    code = code_of(text)
    lead = f"error[{code}]: " if code else "error: "
    return lead + bounded_line(text, LINE_LIMIT - len(lead) - len(hint)) + hint
