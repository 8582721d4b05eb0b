"""`snakebot bus play`: play a gait table through a bus adapter with no controller, the
host as bus master running the controller's own gait player."""

from __future__ import annotations

import sys
import time

import click

from snakebot.cli.bus import EXIT_INTERRUPTED, bus_options
from snakebot.cli.output import dumps
from snakebot.facts import devices
from snakebot.formats.gaittable import GaitTable, read_gait
from snakebot.formats.register_values import BusCommandError
from snakebot.link.bus.scan import identify
from snakebot.link.transport import DxlClient
from snakebot.model.player import (
    FULL_SPEED,
    GOAL_BLOCK,
    GOAL_POSITION_ADDR,
    START_SETTLE_S,
    START_SPEED,
    TICK_MS,
    PlayerError,
    TablePlayer,
    goal_block,
    goal_blocks,
)

STOP_S = 0.5
"""How long a Ctrl-C stop takes: the gait slows to a halt over this time."""

_AX12 = devices.ax12()
_PRESENT = _AX12.register("Present Position")
_SPEED = _AX12.register("Moving Speed")


def _paced(port: str) -> str:
    """``port``, with the emulated bus of a ``sim://`` URL tied to the wall clock: the
    player ticks on the wall clock, so the servos must move in its time too (otherwise
    the emulated bus runs only while the host waits for a reply, and the servos would
    hardly move during the gait). A URL that names its own ``realtime`` is left alone,
    as is ``sim://NAME`` with no options (a bus opened earlier keeps its own)."""
    if not port.startswith("sim://") or "realtime=" in port or "?" not in port:
        return port
    return port + ("" if port.endswith(("?", "&")) else "&") + "realtime=1"


def _check_servos(client: DxlClient, table: GaitTable) -> None:
    missing = [sid for sid in table.joint_ids if identify(client, sid) is None]
    if missing:
        raise BusCommandError(
            f"servo{'s' if len(missing) > 1 else ''} {', '.join(map(str, missing))} of the "
            f"gait do{'' if len(missing) > 1 else 'es'} not answer at {client.baudrate} baud: "
            "check power and cabling, and find the servos with snakebot bus scan"
        )


def _move_to_start(client: DxlClient, table: GaitTable) -> None:
    """Send every joint to the first frame at a gentle speed and wait until it is there."""
    first = [int(g) for g in table.frames[0]]
    here = [client.read_u16(sid, _PRESENT.address) for sid in table.joint_ids]
    client.sync_write(
        GOAL_POSITION_ADDR,
        GOAL_BLOCK,
        {sid: goal_block(g, START_SPEED) for sid, g in zip(table.joint_ids, first, strict=True)},
    )
    distance = max(abs(h - g) for h, g in zip(here, first, strict=True))
    ticks_per_s = _SPEED.to_units(START_SPEED, "deg/s") * _AX12.require_position().scale.per_unit(
        "deg"
    )
    time.sleep(distance / ticks_per_s + START_SETTLE_S)


@click.command("play")
@click.argument("gait", type=click.Path(dir_okay=False))
@bus_options
@click.option("--loop", is_flag=True, help="Play the gait over and over until Ctrl-C.")
def bus_play(port: str, baud: int, as_json: bool, gait: str, loop: bool) -> None:
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
    if loop and not table.loop:
        raise BusCommandError(
            f"{gait} is a gait played once (its last frame does not lead back to the first): "
            "drop --loop, or make a looping gait"
        )
    try:
        player = TablePlayer(table, loop=loop)
    except PlayerError as exc:
        raise BusCommandError(f"{gait}: {exc}") from None
    pass_ms = table.frame_period_ms * (table.frame_count if table.loop else table.frame_count - 1)
    with DxlClient(_paced(port), baud) as client:
        _check_servos(client, table)
        _move_to_start(client, table)
        ticks, stopped_at = _play(client, player, pass_ms, loop, as_json)
        held = {sid: client.read_u16(sid, _PRESENT.address) for sid in table.joint_ids}
    report = {
        "gait": gait,
        "port": port,
        "ticks": ticks,
        "stopped_by_user": stopped_at is not None,
        "played_s": ticks * TICK_MS / 1000,
        "present_position": held,
    }
    if as_json:
        click.echo(dumps(report))
    else:
        how = "stopped by Ctrl-C" if stopped_at is not None else "finished"
        click.echo(
            f"Played {report['played_s']:.2f} s of {gait} ({how}); the servos hold at "
            + ", ".join(f"{sid}: {pos}" for sid, pos in held.items())
        )
    if stopped_at is not None:
        sys.exit(EXIT_INTERRUPTED)


def _play(
    client: DxlClient, player: TablePlayer, pass_ms: int, loop: bool, quiet: bool
) -> tuple[int, int | None]:
    """Tick the player on the wall clock and send each tick's SYNC_WRITE; on Ctrl-C, slow
    it to a halt. Returns the ticks sent and the tick Ctrl-C came at (None if none)."""
    total = None if loop else pass_ms // TICK_MS + 1
    bar = click.progressbar(
        length=total or 0, label="Playing", file=sys.stderr, hidden=quiet or total is None
    )
    stop_ticks = round(STOP_S * 1000 / TICK_MS)
    stopped_at: int | None = None
    n = 0
    start = time.monotonic()
    with bar:
        while total is None or n < total or stopped_at is not None:
            try:
                if stopped_at is not None:
                    k = n - stopped_at
                    if k > stop_ticks:
                        break
                    player.speed_scale = max(1, round(FULL_SPEED * (1 - k / stop_ticks)))
                delay = start + n * TICK_MS / 1000 - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                outputs = player.tick(n * TICK_MS)
                if outputs:
                    client.sync_write(GOAL_POSITION_ADDR, GOAL_BLOCK, goal_blocks(outputs))
                n += 1
                bar.update(1)
                if stopped_at is None and not loop and player.finished:
                    break
            except KeyboardInterrupt:
                if stopped_at is not None:
                    break  # a second Ctrl-C: stop at once
                stopped_at = n
    return n, stopped_at
