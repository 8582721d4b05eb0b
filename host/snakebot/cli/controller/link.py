"""Options shared by the commands that talk to the controller (upload, play, stop,
serpenoid, monitor): --port, --baud, --id and --json, and opening the link."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import click

from snakebot.cli.params import controller_port
from snakebot.facts.boards import PC_LINK_BAUD
from snakebot.link.controller import load
from snakebot.link.controller.client import ControllerClient

PORT_HELP = (
    "The controller's PC link: the CM-530's USB-serial device (/dev/ttyUSB0, COM3), a "
    "pyserial URL, or the pseudo-terminal of the emulated controller (`snakebot sim "
    "serve` prints it; sim:// URLs emulate servos only)."
)


def _link_baud(ctx: click.Context, param: click.Parameter, value: int) -> int:
    """A rate no slower than the slowest a Dynamixel device is tabulated at: below it a
    reply's timeout (which scales with the byte time) would run to minutes."""
    from snakebot.formats.register_values import slowest_bps

    slowest = slowest_bps()
    if value < slowest:
        raise click.BadParameter(
            f"{value} bit/s is slower than any Dynamixel device runs (the slowest: {slowest}); "
            f"the firmware's PC link runs at {PC_LINK_BAUD}",
            ctx,
            param,
        )
    return value


controller_id_option = click.option(
    "--id",
    "controller_id",
    type=click.IntRange(0, 253),
    default=load().default_id,
    show_default=True,
    envvar="SNAKEBOT_CONTROLLER_ID",
    help="The controller's Protocol 1.0 ID on the PC link.",
)
"""--id, for every command that talks to the controller."""


def controller_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--port, --baud, --id and --json."""

    @click.option(
        "--port",
        "-p",
        required=True,
        envvar="SNAKEBOT_PORT",
        show_envvar=True,
        callback=controller_port("snakebot sim serve"),
        help=PORT_HELP,
    )
    @click.option(
        "--baud",
        "-b",
        type=click.IntRange(min=1),
        callback=_link_baud,
        default=PC_LINK_BAUD,
        show_default=True,
        help="Bit rate of the PC link (the firmware's: 57600).",
    )
    @controller_id_option
    @click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        return func(*args, **kwargs)

    return wrapper


def open_controller(port: str, baud: int, controller_id: int) -> ControllerClient:
    """The controller client on ``port`` (PortError, exit 2, if it cannot be opened)."""
    return ControllerClient.open(port, baud, controller_id)
