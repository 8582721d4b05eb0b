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
from snakebot.cli.demo import demo  # noqa: E402

main.add_command(demo)
from snakebot.cli.sim import sim  # noqa: E402

main.add_command(sim)
from snakebot.cli.flash import flash_command  # noqa: E402

main.add_command(flash_command)
from snakebot.cli.sim_bootloader import bootloader  # noqa: E402

sim.add_command(bootloader)
from snakebot.cli.bus import bus  # noqa: E402

main.add_command(bus)
from snakebot.cli.model import model  # noqa: E402

main.add_command(model)
from snakebot.cli.gait import gait  # noqa: E402

main.add_command(gait)
from snakebot.cli.upload import upload  # noqa: E402

main.add_command(upload)
from snakebot.cli.playback import play, serpenoid, stop  # noqa: E402

main.add_command(play)
main.add_command(stop)
main.add_command(serpenoid)
from snakebot.cli.monitor import monitor  # noqa: E402

main.add_command(monitor)
from snakebot.cli.sim_predict import predict  # noqa: E402

sim.add_command(predict)
from snakebot.cli.sim_serve import serve  # noqa: E402

sim.add_command(serve)
