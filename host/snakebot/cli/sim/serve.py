"""`snakebot sim serve`: the emulated robot with its real firmware on an emulated board."""

from __future__ import annotations

import math
import time
from pathlib import Path

import click

from snakebot.cli.options import (
    FOXGLOVE_RATE_HZ,
    board_option,
    firmware_option,
    foxglove_option,
    json_option,
    robot_option,
    world_option,
)
from snakebot.cli.output import dumps
from snakebot.cli.params import NumberType
from snakebot.cli.signals import StopRequest, serving
from snakebot.sim.serve import BodyPose, EmulatedRobot

HISTORY_S = 600.0
"""Seconds of the world's latest samples kept while serving: memory stays flat however
long it serves (the pose reports need only the latest)."""


@click.command("serve")
@robot_option("Robot to emulate, with its servo IDs, zero ticks and body", default="snake5")
@board_option
@firmware_option
@click.option(
    "--sim-options",
    metavar="QUERY",
    default="",
    help="Emulator options as in a sim:// URL, e.g. 'corrupt=0.001&seed=3' or "
    "'brownout=10@5+1' (see `snakebot sim bus --help`).",
)
@world_option(
    note="On mujoco the body moves the servos: the position, speed and load the firmware "
    "reads come from the physics."
)
@click.option(
    "--report",
    type=NumberType(0),
    default=5.0,
    show_default=True,
    help="Seconds between lines giving the body's pose in the world (0: never).",
)
@foxglove_option(
    "the emulated robot (its pose from the world; on mujoco its bodies on /scene, as "
    "Foxglove's own SceneUpdate)"
)
@json_option("first where everything is (pc_link, bus_socket, qemu_pid, ...), then the body's pose")
def serve(
    robot: str,
    board: str,
    firmware: Path | None,
    sim_options: str,
    world: str,
    report: float,
    foxglove: tuple[str, int] | None,
    as_json: bool,
) -> None:
    """Run the controller firmware on the emulated robot until Ctrl-C.

    By default the CM-530's own image runs on the emulated STM32F103RE; --board qemu runs
    the qemu board's build under QEMU instead. The firmware's Dynamixel bus (USART1) drives
    the robot's emulated AX-12s, and its PC link (USART3) is a pseudo-terminal, printed at
    the start: give it as --port to any snakebot command, exactly as the CM-530's
    USB-serial port, e.g.

    \b
        snakebot sim serve --robot snake5
        snakebot upload walk.gait --port /dev/pts/N      # in another shell
        snakebot play --port /dev/pts/N --loop
        snakebot monitor --port /dev/pts/N
        snakebot sim serve --foxglove 8765                # then ws://127.0.0.1:8765

    The world moves the robot's body from the servos' positions while it serves; its pose
    is printed every --report seconds (x forward along the head link's first heading).
    Ctrl-C or SIGTERM stops the emulator and the emulated bus, nothing left running, and
    exits 130 or 143.
    Build the firmware first with `make firmware`.
    """
    emulated = EmulatedRobot(
        robot, firmware, sim_query=sim_options, world=world, history_s=HISTORY_S, board=board
    )
    with serving() as stop:
        try:
            _serve(emulated, report, foxglove, as_json, stop)
        finally:
            emulated.stop()
    stop.exit_by_signal()


def _serve(
    emulated: EmulatedRobot,
    report: float,
    foxglove: tuple[str, int] | None,
    as_json: bool,
    stop: StopRequest,
) -> None:
    """Start ``emulated``, say where it serves, and report its pose until ``stop``."""
    live = None
    try:
        info = emulated.start()
        if foxglove is not None:
            from snakebot.workflows.foxglove import FoxgloveLive

            live = FoxgloveLive(emulated.robot, *foxglove)
        extra = {} if live is None else {"foxglove": f"ws://{foxglove[0]}:{live.port}"}
        if as_json:
            click.echo(dumps({"event": "serving", **info.as_dict(), **extra}))
        else:
            click.echo(f"emulated {info.robot}: firmware {info.firmware} {info.where()}")
            click.echo(
                f"PC link (USART3): {info.pc_link}  ({info.baudrate} baud, controller "
                f"ID {info.controller_id}): snakebot monitor --port {info.pc_link}"
            )
            click.echo(
                f"bus (USART1): emulated servos {', '.join(map(str, info.servo_ids))} "
                f"on {info.bus_socket or 'the chip clock'}"
            )
            if live is not None:
                click.echo(
                    f"Foxglove: open {extra['foxglove']} (Open connection, Foxglove WebSocket)"
                )
            click.echo("Ctrl-C stops.")
        wait = report if report > 0 else 0.5
        tick = 1.0 / FOXGLOVE_RATE_HZ if live is not None else wait
        stream = None
        if live is not None:
            from snakebot.workflows.foxglove import EmulatedStream

            stream = EmulatedStream(live, emulated)
        next_report = time.monotonic() + wait
        while not stop.wait(tick):
            emulated.check_running()
            if stream is not None:
                stream.tick()
            if time.monotonic() >= next_report:
                next_report += wait
                if report > 0:
                    _print_pose(emulated.pose(), as_json)
        _print_pose(emulated.pose(), as_json, final=True)
    finally:
        if live is not None:
            live.close()


def _print_pose(pose: BodyPose | None, as_json: bool, final: bool = False) -> None:
    if pose is None:
        return
    if as_json:
        click.echo(dumps({"event": "stopped" if final else "pose", **pose.as_dict()}))
    else:
        what = "stopped; body at" if final else "world:"
        click.echo(
            f"{what} t = {pose.t:7.2f} s  x = {100 * pose.x:+7.1f} cm  "
            f"y = {100 * pose.y:+7.1f} cm  heading {math.degrees(pose.theta):+6.1f} deg"
        )
