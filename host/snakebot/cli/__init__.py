"""The ``snakebot`` command line: the top layer, and nothing but a front.

One subpackage per command group with several commands (``bus``, ``controller``,
``gait``, ``sim``) and one module per stand-alone command (``compare``, ``demo``,
``doctor``, ``flash``, ``model``, ``plan``, ``program``, ``robot``); every command is
registered below. A command parses its options, calls one operation from the library
and prints; ``params`` holds the option types, ``output`` the JSON and text writers,
``signals`` the Ctrl-C and hang-up handling. Errors become one line on stderr and an
exit status: 1 runtime failure, 2 bad input, 130 Ctrl-C (see ``errors``).

May import: every layer of the package (``plots``, ``workflows``, ``sim``, ``link``,
``model``, ``formats``, ``facts``, the package root). Nothing in the package imports
it but ``python -m snakebot``.
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

    Start with `snakebot COMMAND --help`. Ports may be device paths (/dev/ttyUSB0) or
    pyserial URLs. The bus commands also take sim:// (emulated servos, in process); the
    controller commands need the emulated controller of `snakebot sim serve`.
    """


# Command registration: each command lives in its own module. Imported here, after
# `main` exists, because the `sim` subcommands attach to the `sim` group.
from snakebot.cli.bus import bus  # noqa: E402
from snakebot.cli.bus.play import bus_play  # noqa: E402
from snakebot.cli.compare import compare_command  # noqa: E402
from snakebot.cli.controller.config import config  # noqa: E402
from snakebot.cli.controller.drive import drive  # noqa: E402
from snakebot.cli.controller.library import library  # noqa: E402
from snakebot.cli.controller.limits import limits  # noqa: E402
from snakebot.cli.controller.monitor import monitor  # noqa: E402
from snakebot.cli.controller.playback import play, serpenoid, stop  # noqa: E402
from snakebot.cli.controller.upload import upload  # noqa: E402
from snakebot.cli.demo import demo  # noqa: E402
from snakebot.cli.doctor import doctor  # noqa: E402
from snakebot.cli.flash import flash_command  # noqa: E402
from snakebot.cli.gait import gait  # noqa: E402
from snakebot.cli.model import model  # noqa: E402
from snakebot.cli.plan import plan_command  # noqa: E402
from snakebot.cli.program import program  # noqa: E402
from snakebot.cli.robot import robot  # noqa: E402
from snakebot.cli.sim import sim  # noqa: E402
from snakebot.cli.sim.bootloader import bootloader  # noqa: E402
from snakebot.cli.sim.goto import goto  # noqa: E402
from snakebot.cli.sim.predict import predict  # noqa: E402
from snakebot.cli.sim.serve import serve  # noqa: E402
from snakebot.cli.sim.thesis import friction, thesis  # noqa: E402

for command in (
    model,
    gait,
    sim,
    upload,
    limits,
    play,
    stop,
    serpenoid,
    monitor,
    bus,
    flash_command,
    demo,
):
    main.add_command(command)
for command in (plan_command, robot, drive, program, config, doctor, compare_command, library):
    main.add_command(command)
bus.add_command(bus_play)
for command in (predict, serve, bootloader, goto, thesis, friction):
    sim.add_command(command)
