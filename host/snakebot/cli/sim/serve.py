"""`snakebot sim serve`: the emulated robot with its real firmware under QEMU."""

from __future__ import annotations

import math
import signal
import threading
from pathlib import Path
from types import FrameType

import click

from snakebot.cli.output import dumps
from snakebot.cli.params import NumberType
from snakebot.cli.signals import STOP_SIGNALS
from snakebot.sim.errors import SimFailure
from snakebot.sim.physics.select import DEFAULT_WORLD, WORLDS
from snakebot.sim.serve import EmulatedRobot

HISTORY_S = 600.0
"""Seconds of the world's latest samples kept while serving: memory stays flat however
long it serves (the pose reports need only the latest)."""


@click.command("serve")
@click.option(
    "--robot",
    "-r",
    default="snake5",
    show_default=True,
    help="Robot to emulate: snake3, trident, snake5 or a robot TOML file (its "
    "servo IDs, zero ticks and body).",
)
@click.option(
    "--firmware",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Firmware for QEMU: the qemu board's application ELF (the boot stub beside it "
    "goes in front) or a whole-flash .bin image. Default: build/qemu/firmware.elf from "
    "`make firmware` in a checkout, else the image shipped with snakebot.",
)
@click.option(
    "--sim-options",
    metavar="QUERY",
    default="",
    help="Emulator options as in a sim:// URL, e.g. 'corrupt=0.001&seed=3' or "
    "'brownout=10@5+1' (see `snakebot sim bus --help`).",
)
@click.option(
    "--world",
    type=click.Choice(WORLDS),
    default=DEFAULT_WORLD,
    show_default=True,
    help="kinematic: the minimum-slip model moves the body from the servos' positions; "
    "mujoco: the body in MuJoCo (mass, slipping wheels) moves the servos, whose "
    "position, speed and load the firmware reads come from the physics.",
)
@click.option(
    "--report",
    type=NumberType(0),
    default=5.0,
    show_default=True,
    help="Seconds between lines giving the body's pose in the world (0: never).",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print JSON lines: first where everything is (pc_link, bus_socket, "
    "qemu_pid, ...), then the body's pose.",
)
def serve(
    robot: str,
    firmware: Path | None,
    sim_options: str,
    world: str,
    report: float,
    as_json: bool,
) -> None:
    """Run the controller firmware in QEMU on the emulated robot until Ctrl-C.

    The firmware's Dynamixel bus (USART1) drives the robot's emulated AX-12s over a Unix
    socket, and its PC link (USART3) is a pseudo-terminal, printed at the start: give it
    as --port to any snakebot command, exactly as the CM-530's USB-serial port, e.g.

    \b
        snakebot sim serve --robot snake5
        snakebot upload walk.gait --port /dev/pts/N      # in another shell
        snakebot play --port /dev/pts/N --loop
        snakebot monitor --port /dev/pts/N

    The world moves the robot's body from the servos' positions while it serves; its pose
    is printed every --report seconds (x forward along the head link's first heading).
    Ctrl-C or SIGTERM stops QEMU and the emulated bus; nothing is left running. Build the
    firmware first with `make firmware`.
    """
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in STOP_SIGNALS}
    emulated = EmulatedRobot(
        robot, firmware, sim_query=sim_options, world=world, history_s=HISTORY_S
    )
    try:
        info = emulated.start()
        if as_json:
            click.echo(dumps({"event": "serving", **info.as_dict()}))
        else:
            click.echo(
                f"emulated {info.robot}: firmware {info.firmware} in QEMU (pid {info.qemu_pid})"
            )
            click.echo(
                f"PC link (USART3): {info.pc_link}  ({info.baudrate} baud, controller "
                f"ID {info.controller_id}): snakebot monitor --port {info.pc_link}"
            )
            click.echo(
                f"bus (USART1): emulated servos {', '.join(map(str, info.servo_ids))} "
                f"on {info.bus_socket}"
            )
            click.echo("Ctrl-C stops.")
        wait = report if report > 0 else 0.5
        while not stop.wait(wait):
            if not emulated.running:
                raise SimFailure(
                    "QEMU or the emulated bus stopped unexpectedly: "
                    f"{emulated.qemu.log().strip() or 'no message'}"
                )
            if report > 0:
                _pose(emulated, as_json)
        _pose(emulated, as_json, final=True)
    finally:
        emulated.stop()
        for s, handler in previous.items():
            signal.signal(s, handler)


def _pose(emulated: EmulatedRobot, as_json: bool, final: bool = False) -> None:
    record = emulated.record()
    if not len(record.t):
        return
    x, y, theta = (float(v) for v in record.pose[-1])
    t = float(record.t[-1])
    if as_json:
        click.echo(
            dumps(
                {
                    "event": "stopped" if final else "pose",
                    "t": round(t, 3),
                    "x": round(x, 6),
                    "y": round(y, 6),
                    "theta": round(theta, 6),
                }
            )
        )
    else:
        what = "stopped; body at" if final else "world:"
        click.echo(
            f"{what} t = {t:7.2f} s  x = {100 * x:+7.1f} cm  y = {100 * y:+7.1f} cm  "
            f"heading {math.degrees(theta):+6.1f} deg"
        )
