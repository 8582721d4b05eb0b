"""`snakebot bus play`: play a gait table through a bus adapter with no controller, the
host as bus master running the controller's own gait player."""

from __future__ import annotations

import sys

import click

from snakebot.cli.options import BusLink, bus_options
from snakebot.cli.output import dumps
from snakebot.cli.params import INPUT_TEXT_PATH
from snakebot.cli.signals import interrupted_status
from snakebot.formats.gaittable import read_gait
from snakebot.link.bus.play import play_table, player_for, tick_count


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
def bus_play(bus: BusLink, as_json: bool, gait: str, loop: bool) -> None:
    """Play the gait table GAIT on servos connected through a bus adapter (USB2Dynamixel,
    U2D2), with no controller: this computer is the bus master and runs the
    controller's own gait player, sending one SYNC_WRITE of goal positions and speeds
    every 10 ms control tick.

    The servos first move gently to the gait's first frame. Ctrl-C slows the gait to a
    halt over half a second; the servos then hold their positions (torque stays on).

    \b
        snakebot bus play crawl.gait --port /dev/ttyUSB0
        snakebot bus play crawl.gait --port /dev/ttyUSB0 --loop
    """
    table = read_gait(gait)
    player = player_for(table, loop, gait)
    total = tick_count(table, loop)
    bar = click.progressbar(
        length=total or 0, label="Playing", file=sys.stderr, hidden=as_json or total is None
    )
    with BusLink(_paced(bus.port), bus.baud).open() as client, bar:
        played = play_table(client, table, player, loop, on_tick=lambda: bar.update(1))
    report = {
        "gait": gait,
        "port": bus.port,
        "ticks": played.ticks,
        "stopped_by_user": played.stopped_at is not None,
        "played_s": played.seconds,
        "present_position": played.held,
    }
    if as_json:
        click.echo(dumps(report))
    else:
        how = "stopped by Ctrl-C" if played.stopped_at is not None else "finished"
        click.echo(
            f"Played {report['played_s']:.2f} s of {gait} ({how}); the servos hold at "
            + ", ".join(f"{sid}: {pos}" for sid, pos in played.held.items())
        )
    if played.stopped_at is not None:
        sys.exit(interrupted_status())
