"""`snakebot limits set` and `snakebot limits show`: the robot's joint limits on the
controller, which makes its servos enforce them."""

from __future__ import annotations

import click

from snakebot.cli.options import ControllerLink, controller_options
from snakebot.cli.output import dumps
from snakebot.link.controller.limits import (
    limits_state,
    robot_limits,
    robot_torque_limit,
    set_limits,
    torque_fields,
    torque_text,
)
from snakebot.model.robots import load_robot


@click.group("limits")
def limits() -> None:
    """The robot's joint limits, kept by the controller and enforced by the servos.

    Once set, the controller makes every servo's CW/CCW Angle Limit equal to the
    robot's limits (writing a servo's EEPROM only where it differs), so a servo refuses
    a goal outside them even if the bus damages a packet; it refuses gait tables that
    reach beyond them, and it will not play until every servo holds them. A robot file
    may also set one torque limit for all servos (`[limits] torque = "60%"`, of stall
    torque): the controller holds every servo's Torque Limit to it, and writes it again
    after a servo's power cycle resets it.

    \b
        snakebot limits set snake5 --port /dev/ttyUSB0
        snakebot limits show --port /dev/ttyUSB0
    """


@limits.command("set")
@click.argument("robot", metavar="ROBOT")
@controller_options
def set_command(robot: str, link: ControllerLink, as_json: bool) -> None:
    """Set the limits of ROBOT (snake3, snake5, trident or a .toml file) on the
    controller, and wait until its servos hold them.

    Stops any motion. Tables generated from another robot file (wider limits, or other
    servo IDs) are refused afterwards: regenerate them with `snakebot gait` from ROBOT.
    """
    model = load_robot(robot)  # a bad robot file fails before the port opens
    with link.open() as ctl:
        ctl.identify()
        report = set_limits(ctl, robot_limits(model), torque=model.torque_limit)
    click.echo(dumps(report.as_dict()) if as_json else report.summary())


@limits.command("show")
@controller_options
def show_command(link: ControllerLink, as_json: bool) -> None:
    """Whether the controller has robot limits, the torque limit they hold the servos to
    (in % of stall torque), and whether its servos hold them (NONE: no limits set;
    APPLYING: being checked; VERIFIED; FAILED: a servo did not take them or did not
    answer)."""
    with link.open() as ctl:
        ctl.identify()
        state, count = limits_state(ctl)
        torque = robot_torque_limit(ctl)
    if as_json:
        click.echo(dumps({"state": state, "count": count, **torque_fields(torque)}))
    elif count == 0:
        click.echo("no robot limits set: `snakebot limits set ROBOT` sets them")
    else:
        held = "angle limits" if torque is None else "angle and torque limits"
        click.echo(
            f"robot limits for {count} servos, torque limit {torque_text(torque)}; the "
            f"servos' {held} are {state}"
        )
