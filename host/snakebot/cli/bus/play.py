"""`snakebot bus play`: play a gait table through a bus adapter with no controller, the
host as bus master running the controller's own gait player."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

import click

from snakebot.cli.options import (
    FOXGLOVE_RATE_HZ,
    BusLink,
    bus_options,
    foxglove_option,
    robot_option,
)
from snakebot.cli.output import dumps
from snakebot.cli.params import INPUT_TEXT_PATH
from snakebot.cli.signals import interrupted_status
from snakebot.formats.gaittable import GaitTable, read_gait
from snakebot.link.bus.play import play_table, player_for, tick_count
from snakebot.model.player import FULL_SPEED, TICK_MS

if TYPE_CHECKING:
    from snakebot.link.transport import DxlClient
    from snakebot.model.player import TablePlayer


def _paced(port: str) -> str:
    """``port``; a ``sim://`` URL with its bus on the wall clock, as the player is."""
    if not port.startswith("sim://"):
        return port  # a real bus keeps the wall clock's time itself
    from snakebot.sim.urlhandler.protocol_sim import wall_clock_url

    return wall_clock_url(port)


@click.command("play")
@click.argument("gait", type=INPUT_TEXT_PATH)
@bus_options
@click.option("--loop", is_flag=True, help="Play the gait over and over until Ctrl-C.")
@robot_option(
    "With --foxglove: the robot the gait drives, for its joints and its predicted pose",
    otherwise="the one the gait's metadata names",
)
@foxglove_option("the servos (read back over the bus) and the predicted pose, as the gait plays")
def bus_play(
    bus: BusLink,
    as_json: bool,
    gait: str,
    loop: bool,
    robot: str | None,
    foxglove: tuple[str, int] | None,
) -> None:
    """Play the gait table GAIT on servos connected through a bus adapter (USB2Dynamixel,
    U2D2), with no controller: this computer is the bus master and runs the
    controller's own gait player, sending one SYNC_WRITE of goal positions and speeds
    every 10 ms control tick.

    The servos first move gently to the gait's first frame. Ctrl-C slows the gait to a
    halt over half a second; the servos then hold their positions (torque stays on).
    If this computer falls behind the gait (a busy machine), the servos lag it; they are
    then brought to its last goal gently at the end, and the output says so.

    \b
        snakebot bus play crawl.gait --port /dev/ttyUSB0
        snakebot bus play crawl.gait --port /dev/ttyUSB0 --loop
        snakebot bus play crawl.gait --port /dev/ttyUSB0 --robot snake5 --foxglove 8765

    With --foxglove each servo is also read back over the bus (one READ apiece, a few
    times a second up to 50) and streamed to Foxglove with the pose the kinematic model
    predicts from its angles.
    """
    table = read_gait(gait)
    player = player_for(table, loop, gait)
    total = tick_count(table, loop)
    bar = click.progressbar(
        length=total or 0, label="Playing", file=sys.stderr, hidden=as_json or total is None
    )
    with contextlib.ExitStack() as stack:
        client = stack.enter_context(BusLink(_paced(bus.port), bus.baud).open())
        on_tick = _live(stack, table, robot, foxglove, client, player) if foxglove else None
        stack.enter_context(bar)

        def tick() -> None:
            bar.update(1)
            if on_tick is not None:
                on_tick()

        played = play_table(client, table, player, loop, on_tick=tick)
    report = {
        "gait": gait,
        "port": bus.port,
        "ticks": played.ticks,
        "stopped_by_user": played.stopped_at is not None,
        "played_s": played.seconds,
        "present_position": played.held,
        "host_late_ms": round(played.late_s * 1000, 1),
        "moved_to_last_goal": played.caught_up,
    }
    if as_json:
        click.echo(dumps(report))
    else:
        how = "stopped by Ctrl-C" if played.stopped_at is not None else "finished"
        click.echo(
            f"Played {report['played_s']:.2f} s of {gait} ({how}); the servos hold at "
            + ", ".join(f"tick {pos} (servo {sid})" for sid, pos in played.held.items())
        )
        if played.caught_up:
            click.echo(
                f"The host fell up to {played.late_s * 1000:.0f} ms behind the gait (a busy "
                "machine): the servos lagged it and were brought to its last goal gently "
                "at the end. Play it again with less running beside it."
            )
    if played.stopped_at is not None:
        sys.exit(interrupted_status())


def _live(
    stack: contextlib.ExitStack,
    table: GaitTable,
    robot: str | None,
    endpoint: tuple[str, int],
    client: DxlClient,
    player: TablePlayer,
) -> Callable[[], None]:
    """The Foxglove server (closed with ``stack``) and what each control tick sends it."""
    from snakebot.workflows.foxglove import BusStream, FoxgloveLive
    from snakebot.workflows.predict import resolve_robot

    chosen = resolve_robot(table, robot)
    server = stack.enter_context(FoxgloveLive(chosen, *endpoint))
    click.echo(f"Foxglove: open ws://{endpoint[0]}:{server.port}", err=True)
    stream = BusStream(chosen, server, round(1000 / (FOXGLOVE_RATE_HZ * TICK_MS)))
    ticks = iter(range(1 << 62))

    def on_tick() -> None:
        state = "playing" if player.speed_scale >= FULL_SPEED else "stopping"
        stream.tick(client, next(ticks), TICK_MS / 1000, {"state": state})

    return on_tick
