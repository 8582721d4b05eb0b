"""Playing a gait table through a bus adapter with no controller: this computer is the
bus master and runs the controller's own gait player, sending one SYNC_WRITE of goal
positions and speeds every control tick (``snakebot bus play``)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from snakebot.facts import devices
from snakebot.formats import protocol
from snakebot.formats.gaittable import GaitTable
from snakebot.formats.register_values import BusCommandError
from snakebot.link.bus.scan import identify
from snakebot.link.transport import DxlClient
from snakebot.model.player import (
    FULL_SPEED,
    GOAL_BLOCK,
    GOAL_POSITION_ADDR,
    START_SETTLE_S,
    START_SPEED,
    START_TOLERANCE_TICKS,
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
_GOAL = _AX12.register("Goal Position")
_PRESENT_SPEED = _AX12.register("Present Speed")
_PRESENT_LOAD = _AX12.register("Present Load")
_LOOK_SPAN = _PRESENT_LOAD.address + 2 - _GOAL.address
"""One READ from Goal Position through Present Load: what a look at a servo takes."""


@dataclass(frozen=True)
class Played:
    """What :func:`play_table` did: the ticks sent, the tick Ctrl-C came at (None if it
    did not) and where each servo holds afterwards."""

    ticks: int
    stopped_at: int | None
    held: dict[int, int]
    late_s: float = 0.0
    """The longest the host sent a tick after its time (a busy host falls behind)."""
    caught_up: bool = False
    """Whether the servos were behind the last frame at the end, and were moved to it."""

    @property
    def seconds(self) -> float:
        return self.ticks * TICK_MS / 1000


def player_for(table: GaitTable, loop: bool, name: str) -> TablePlayer:
    """The controller's player for ``table`` (``name`` says which file in messages)."""
    if loop and not table.loop:
        raise BusCommandError(
            f"{name} is a gait played once (its last frame does not lead back to the first): "
            "play it once, or make a looping gait"
        ).about("loop")
    try:
        return TablePlayer(table, loop=loop)
    except PlayerError as exc:
        raise BusCommandError(f"{name}: {exc}") from None


def tick_count(table: GaitTable, loop: bool) -> int | None:
    """The ticks one pass of ``table`` takes (None when it loops until stopped)."""
    pass_ms = table.frame_period_ms * (table.frame_count if table.loop else table.frame_count - 1)
    return None if loop else pass_ms // TICK_MS + 1


def check_servos(client: DxlClient, table: GaitTable) -> None:
    """Every servo of the table answers, else a :class:`BusCommandError` naming them."""
    missing = [sid for sid in table.joint_ids if identify(client, sid) is None]
    if missing:
        raise BusCommandError(
            f"servo{'s' if len(missing) > 1 else ''} {', '.join(map(str, missing))} of the "
            f"gait do{'' if len(missing) > 1 else 'es'} not answer at {client.baudrate} baud: "
            "check power and cabling, and find the servos with snakebot bus scan"
        )


def move_to_start(client: DxlClient, table: GaitTable) -> None:
    """Send every joint to the first frame at a gentle speed and wait until it is there."""
    move_gently(client, table.joint_ids, [int(g) for g in table.frames[0]])


def move_gently(client: DxlClient, ids: Sequence[int], goals: Sequence[int]) -> None:
    """Send servos ``ids`` to ``goals`` at the start's gentle speed and wait until they are
    there."""
    here = [client.read_u16(sid, _PRESENT.address) for sid in ids]
    client.sync_write(
        GOAL_POSITION_ADDR,
        GOAL_BLOCK,
        {sid: goal_block(g, START_SPEED) for sid, g in zip(ids, goals, strict=True)},
    )
    distance = max(abs(h - g) for h, g in zip(here, goals, strict=True))
    ticks_per_s = _SPEED.to_units(START_SPEED, "deg/s") * _AX12.require_position().scale.per_unit(
        "deg"
    )
    time.sleep(distance / ticks_per_s + START_SETTLE_S)


def play_table(
    client: DxlClient,
    table: GaitTable,
    player: TablePlayer,
    loop: bool,
    on_tick: Callable[[], None] = lambda: None,
) -> Played:
    """Check the servos, move them to the first frame, then tick the player on the wall
    clock and send each tick's SYNC_WRITE; Ctrl-C slows it to a halt over
    :data:`STOP_S` (a second Ctrl-C stops at once). The servos hold where they end.

    A host that falls behind its ticks (a busy machine) sends the late ones at once; the
    servos, told each frame's speed, then lag the gait by the time lost. At the end (unless
    stopped by Ctrl-C), servos left more than the compliance margin from the last goal
    sent are brought to it at the start's gentle speed, and :attr:`Played.late_s` says
    how far behind the host fell."""
    check_servos(client, table)
    move_to_start(client, table)
    total = tick_count(table, loop)
    stop_ticks = round(STOP_S * 1000 / TICK_MS)
    stopped_at: int | None = None
    n = 0
    late = 0.0
    sent: dict[int, int] = {}
    start = time.monotonic()
    while total is None or n < total or stopped_at is not None:
        try:
            if stopped_at is not None:
                k = n - stopped_at
                if k > stop_ticks:
                    break
                player.speed_scale = max(1, round(FULL_SPEED * (1 - k / stop_ticks)))
            due = start + n * TICK_MS / 1000
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            outputs = player.tick(n * TICK_MS)
            if outputs:
                client.sync_write(GOAL_POSITION_ADDR, GOAL_BLOCK, goal_blocks(outputs))
                sent.update((sid, goal) for sid, (goal, _) in outputs.items())
                late = max(late, time.monotonic() - due)
            n += 1
            on_tick()
            if stopped_at is None and not loop and player.finished:
                break
        except KeyboardInterrupt:
            if stopped_at is not None:
                break  # a second Ctrl-C: stop at once
            stopped_at = n
    held = _settled(client, table.joint_ids)
    behind = stopped_at is None and any(
        abs(held[sid] - goal) > START_TOLERANCE_TICKS for sid, goal in sent.items()
    )
    if behind:
        move_gently(client, list(sent), list(sent.values()))
        held = _settled(client, table.joint_ids)
    return Played(n, stopped_at, held, late, behind)


HOLD_SETTLE_S = 1.0
"""The longest wait, after the last goal, for the servos to come to rest before their
held positions are read (an AX-12 lags its goal by tens of milliseconds)."""
HOLD_POLL_S = 0.02


def _settled(client: DxlClient, ids: Sequence[int]) -> dict[int, int]:
    """The servos' present positions once two reads a poll apart agree to a tick (or
    after ``HOLD_SETTLE_S``): where they hold, not where they were still moving."""
    deadline = time.monotonic() + HOLD_SETTLE_S
    last = {sid: client.read_u16(sid, _PRESENT.address) for sid in ids}
    while time.monotonic() < deadline:
        time.sleep(HOLD_POLL_S)
        now = {sid: client.read_u16(sid, _PRESENT.address) for sid in ids}
        if all(abs(now[sid] - last[sid]) <= 1 for sid in ids):
            return now
        last = now
    return last


@dataclass(frozen=True)
class ServoLook:
    """One servo as a READ found it: goal and present position (ticks), present speed
    (rad/s, + counter-clockwise), load (fraction of the stall torque, + counter-clockwise)
    and the error flags of its reply."""

    goal: int
    position: int
    speed_rad_s: float
    load: float
    error: int


def look(client: DxlClient, ids: Sequence[int]) -> list[ServoLook]:
    """Each servo of ``ids``, one READ apiece (its error flags kept, not raised)."""
    out = []
    for sid in ids:
        reply = client.transact(
            protocol.read(sid, _GOAL.address, _LOOK_SPAN), sid, _LOOK_SPAN, check=False
        )
        data = bytes(reply.params)

        def word(register: devices.Register, data: bytes = data) -> int:
            at = register.address - _GOAL.address
            return int.from_bytes(data[at : at + 2], "little")

        out.append(
            ServoLook(
                word(_GOAL),
                word(_PRESENT),
                _PRESENT_SPEED.to_units(word(_PRESENT_SPEED), "rad/s"),
                _PRESENT_LOAD.to_units(word(_PRESENT_LOAD)) / 100.0,  # percent
                int(reply.code),
            )
        )
    return out
