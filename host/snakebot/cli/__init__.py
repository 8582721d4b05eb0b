"""The ``snakebot`` command line: one small module per command group.

Each module defines a click command or group and is registered below. Commands parse
their options, open what they need, call an operation from the library and print;
errors from the library become one line on stderr and exit status 2 (see ``errors``).
"""

from __future__ import annotations

import click

from snakebot import __version__
from snakebot.cli.errors import SnakebotGroup


@click.group(cls=SnakebotGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="snakebot")
def main() -> None:
    """snakebot: derive gaits for wheeled snake robots, check them, and run them on a
    ROBOTIS CM-530 with AX-12 servos, or on the emulated robot.

    Start with `snakebot COMMAND --help`. Ports may be device paths (/dev/ttyUSB0),
    pyserial URLs, or sim:// for the emulated robot.
    """


# Command registration: one line per command module.
