"""`snakebot drive`: steer the controller's on-board serpenoid live from the keyboard, or
from a script of keys."""

from __future__ import annotations

import contextlib
import math
import sys
import termios
import time
import tty
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import click

from snakebot.cli.options import (
    FOXGLOVE_RATE_HZ,
    ControllerLink,
    controller_options,
    foxglove_option,
    roster_option,
    wave_options,
)
from snakebot.cli.output import dumps
from snakebot.cli.params import EXISTING_INPUT
from snakebot.link.controller import playback
from snakebot.link.controller.drive import SPEED_STEP, STEER_STEP, Driver, Wait, parse_keys
from snakebot.model.robots import load_robot
from snakebot.userfiles import read_text_bounded

REFRESH_S = 0.25
"""Seconds between two looks at the controller on the terminal."""

_KEY_HELP = "left/right steer   up/down speed   space stop/start   q quit"


HELP = f"""Run the controller's serpenoid and steer it live.

On a terminal: left and right arrows turn (Steering Offset, {math.degrees(STEER_STEP):g} deg
a press), up and down change the speed (Speed Scale, {SPEED_STEP:g}x a press), space stops
and starts again, q stops the robot and quits. The screen shows the state, error flags,
and each joint's goal and present angle in degrees, load and errors, a few times a
second. The firmware slews each change, so no servo is asked to jump.

If the controller is running a program already (`snakebot upload X.prog` then `play`),
that program is driven instead: up and down change its speed, left and right steer its
serpenoid segments (its other segments are not steered), space stops it and runs it
again from its start.

With --keys or --script the same keys are handled without a terminal and each is
reported as it is done (with --json, one JSON record per line); the script ends as q
does, stopping the robot. Example:

\b
    snakebot drive --port /dev/ttyUSB0 --robot snake5
    snakebot drive --port /dev/pts/3 --robot snake5 --keys "LL 1s RR 1s q" --json
    snakebot drive --port /dev/ttyUSB0 --robot snake5 --foxglove 8765

With --foxglove the controller is looked at {FOXGLOVE_RATE_HZ:g} times a second (as the
link allows) and each look goes to Foxglove, with --robot the pose predicted from the
joint angles too.
"""


MAX_SCRIPT_BYTES = 1 << 20
"""The largest key script read (a script of a megabyte drives for hours)."""


@click.command("drive", help=HELP)
@controller_options
@roster_option
@click.option(
    "--keys",
    help='Drive without a terminal: these keys, e.g. "LLRR U 2s space q" (left, right, up, '
    "down or the letters L R U D, space, q, and waits such as 0.5s).",
)
@click.option(
    "--script",
    type=EXISTING_INPUT,
    help="Drive without a terminal: the keys in this file, as --keys takes them (# starts "
    "a comment).",
)
@wave_options()
@foxglove_option("the controller's state and its servos, as the robot is driven")
def drive(
    link: ControllerLink,
    as_json: bool,
    robot: str | None,
    amplitude: float,
    omega: float,
    delta: float,
    keys: str | None,
    script: Path | None,
    foxglove: tuple[str, int] | None,
) -> None:
    if keys is not None and script is not None:
        raise click.UsageError("give --keys or --script, not both")
    text = read_text_bounded(script, MAX_SCRIPT_BYTES, "key script") if script is not None else keys
    try:
        scripted = parse_keys(text) if text is not None else None
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="--script" if script else "--keys") from None
    if scripted is None and not (sys.stdin.isatty() and sys.stdout.isatty()):
        raise click.UsageError(
            "snakebot drive needs a terminal for its keys: run it in one, or pass "
            '--keys "..." or --script FILE'
        )
    settings = playback.SerpenoidSettings(amplitude, omega, delta)
    roster = playback.roster_from_robot(load_robot(robot)) if robot else None
    with contextlib.ExitStack() as stack:
        ctl = stack.enter_context(link.open())
        driver = Driver(ctl, settings, roster=roster)
        look_s = REFRESH_S
        if foxglove is not None:
            from snakebot.workflows.foxglove import SampleStream

            stream = SampleStream(robot)
            server = stack.enter_context(stream.serve(*foxglove, name="snakebot drive"))
            click.echo(f"Foxglove: open ws://{foxglove[0]}:{server.port}", err=True)
            driver.on_sample = stream.send
            look_s = 1.0 / FOXGLOVE_RATE_HZ
        driver.start()
        try:
            if scripted is None:
                _terminal(driver, look_s)
            else:
                _scripted(driver, scripted, as_json, look_s if foxglove is not None else None)
        finally:
            if not driver.quit:  # Ctrl-C or a lost link: leave the robot stopped if we can
                with contextlib.suppress(Exception):
                    driver.press("q")


def _scripted(driver: Driver, keys: list[str | Wait], as_json: bool, look_s: float | None) -> None:
    """The keys one by one; during a wait, a look every ``look_s`` if given (a live view)."""
    t0 = time.monotonic()
    for key in [*keys, "q"]:
        if driver.quit:
            break
        if isinstance(key, Wait):
            end = time.monotonic() + key.seconds
            while look_s is not None and time.monotonic() + look_s < end:
                driver.look()
                time.sleep(max(0.0, min(look_s, end - time.monotonic())))
            time.sleep(max(0.0, end - time.monotonic()))
            record: dict[str, Any] = {"wait_s": key.seconds}
        else:
            record = driver.press(key)
        record = {"t": round(time.monotonic() - t0, 3), **record, **driver.look()}
        click.echo(dumps(record) if as_json else _line(record))


def _line(r: dict[str, Any]) -> str:
    what = f"wait {r['wait_s']:g}s" if "wait_s" in r else f"{r['key']}: {r['done']}"
    angles = " ".join(f"{j['name']} {j['position_deg']:+.1f}" for j in r["joints"])
    flags = ",".join(r["error_flags"]) or "none"
    return (
        f"{r['t']:7.2f}s {what} | {r['state']} flags {flags} speed {r['speed']:.2f}x "
        f"steering {r['steer_deg']:+.1f} deg | {angles}"
    )


@contextlib.contextmanager
def _cbreak(fd: int) -> Iterator[None]:
    """Keys arrive one at a time, unechoed; the terminal is restored afterwards."""
    saved = termios.tcgetattr(fd)
    try:
        tty.setcbreak(fd)
        yield
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def _terminal(driver: Driver, look_s: float) -> None:
    try:
        from rich.console import Console
        from rich.live import Live
    except ImportError:
        raise click.ClickException(
            "the terminal UI needs rich: pip install 'snakebot[drive]', or drive with "
            "--keys/--script"
        ) from None
    from snakebot.link.controller.drive import read_key

    fd = sys.stdin.fileno()
    last: dict[str, Any] | None = None
    view = driver.look()
    with _cbreak(fd), Live(_screen(view, last), console=Console(), auto_refresh=False) as live:
        due = time.monotonic() + look_s
        while not driver.quit:
            key = read_key(fd, max(0.0, due - time.monotonic()))
            if key:
                last = driver.press(key)
            if driver.quit:
                break
            if time.monotonic() >= due:
                view = driver.look()
                due = time.monotonic() + look_s
            live.update(_screen(view, last), refresh=True)
        live.update(_screen(driver.look(), last), refresh=True)


def _screen(view: dict[str, Any], last: dict[str, Any] | None) -> Any:
    """The terminal screen: the controller's line, the keys, the last action, the joints."""
    from rich.console import Group
    from rich.table import Table
    from rich.text import Text

    flags = ", ".join(view["error_flags"]) or "none"
    head = Text.assemble(
        ("State ", "bold"),
        view["state"],
        ("   error flags ", "bold"),
        (flags, "red" if view["error_flags"] else ""),
        ("   speed ", "bold"),
        f"{view['speed']:.2f}x",
        ("   steering ", "bold"),
        f"{view['steer_deg']:+.1f} deg",
    )
    done = "" if last is None else f"last key: {last['key']} ({last['done']})"
    table = Table(box=None, header_style="bold")
    for column in ("joint", "id", "goal deg", "angle deg", "load %", "errors"):
        table.add_column(column, justify="left" if column in ("joint", "errors") else "right")
    for j in view["joints"]:
        table.add_row(
            j["name"],
            str(j["id"]),
            f"{j['goal_deg']:+.1f}",
            f"{j['position_deg']:+.1f}",
            f"{j['load_percent']:+.1f}",
            ", ".join(j["error"]) or "-",
        )
    return Group(head, Text(_KEY_HELP, style="dim"), Text(done), table)
