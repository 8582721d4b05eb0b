"""`snakebot play`, `snakebot stop` and `snakebot serpenoid`: run and stop the
controller's gaits."""

from __future__ import annotations

import math
from typing import Any

import click

from snakebot.cli.options import (
    ControllerLink,
    controller_options,
    offset_option,
    roster_option,
    speed_option,
    steer_option,
    wave_options,
)
from snakebot.cli.output import dumps
from snakebot.link.controller import playback
from snakebot.model.robots import load_robot

CLEAR_HELP = "Also clear the error flags and leave the safe state (after fixing its cause)."


def _emit(status: dict[str, Any], as_json: bool, text: str) -> None:
    click.echo(dumps(status) if as_json else text)


def _steer_words(status: dict[str, Any]) -> str:
    return f"steering {math.degrees(status['steer_rad']):+.1f} deg"


@click.command("play")
@controller_options
@click.option(
    "--loop/--once",
    default=None,
    help="Loop the table, or play it once and stop (default: as the table says).",
)
@speed_option
@steer_option
def play(
    link: ControllerLink,
    as_json: bool,
    loop: bool | None,
    speed: float,
    steer: float,
) -> None:
    """Play the controller's gait table from its first frame, or run its program.

    Upload a table or a program first (`snakebot upload`). Speed and steering apply to a
    table at once and can be changed by running play again; a program runs at the speed
    (all its segments) and with the steering (its serpenoid segments only; `snakebot
    drive` changes both while it runs). `snakebot stop` stops.

    \b
        snakebot upload walk.gait --port /dev/ttyUSB0
        snakebot play --port /dev/ttyUSB0 --loop --speed 0.5 --steer 10deg
        snakebot stop --port /dev/ttyUSB0
    """
    with link.open() as ctl:
        status = playback.play(ctl, loop=loop, speed=speed, steer=steer)
    t = status["table"]
    if status.get("program"):
        _emit(
            status,
            as_json,
            f"{status['state']}: the program ({t['joints']} joints, a step every "
            f"{t['period_ms']} ms). Stop it with `snakebot stop --port {link.port}`.",
        )
        return
    how = "looping" if status["loop"] else "once"
    _emit(
        status,
        as_json,
        f"{status['state']}: the table ({t['frames']} frames x {t['joints']} joints every "
        f"{t['period_ms']} ms, {how}) at {status['speed']:.2f}x speed, "
        f"{_steer_words(status)}. Stop it with `snakebot stop --port {link.port}`.",
    )


@click.command("stop")
@controller_options
@click.option("--clear", is_flag=True, help=CLEAR_HELP)
def stop(link: ControllerLink, as_json: bool, clear: bool) -> None:
    """Stop the controller's gait; the servos hold their last position.

    \b
        snakebot stop --port /dev/ttyUSB0
    """
    with link.open() as ctl:
        status = playback.stop(ctl, clear=clear)
    flags = ", ".join(status["error_flags"]) or "none"
    _emit(status, as_json, f"{status['state']} (error flags: {flags})")


@click.command("serpenoid")
@controller_options
@wave_options(required=True)
@offset_option
@steer_option
@speed_option
@roster_option
def serpenoid(
    link: ControllerLink,
    as_json: bool,
    amplitude: float,
    omega: float,
    delta: float,
    offset: float,
    steer: float,
    speed: float,
    robot: str | None,
) -> None:
    """Run the serpenoid gait computed on line by the controller's firmware:

    \b
        phi_k(t) = A sin(omega t + k delta) + phi0

    on every joint k of the controller's roster (the servos of the last uploaded table,
    or those of --robot). No table is needed. A wave that would take a joint past its
    limits (A + |offset| + steer) or move faster than the servo can (A * |omega| *
    speed) is refused, by this command when --robot is given and by the controller
    always (its Refusal Reason says which). Example:

    \b
        snakebot serpenoid --port /dev/ttyUSB0 --robot snake5 -A 30deg -w 180deg -d 120deg
    """
    settings = playback.SerpenoidSettings(amplitude, omega, delta, offset)
    model = load_robot(robot) if robot else None
    roster = playback.roster_from_robot(model) if model else None
    if model is not None:  # before the port is opened: a refusal sends nothing
        playback.check_serpenoid(model, settings, speed=speed, steer=steer)
    with link.open() as ctl:
        status = playback.serpenoid(ctl, settings, speed=speed, steer=steer, roster=roster)
    s = status["serpenoid"]
    _emit(
        status,
        as_json,
        f"{status['state']} on {status['joint_count']} joints: A = "
        f"{math.degrees(s['amplitude_rad']):.1f} deg, omega = "
        f"{math.degrees(s['omega_rad_s']):.1f} deg/s, delta = "
        f"{math.degrees(s['delta_rad']):.1f} deg, phi0 = {math.degrees(s['offset_rad']):.1f} "
        f"deg, {status['speed']:.2f}x speed, {_steer_words(status)}. "
        f"Stop it with `snakebot stop --port {link.port}`.",
    )
