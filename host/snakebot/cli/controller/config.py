"""`snakebot config`: the controller's settings (Safe Action, error masks, Bus Loss Limit,
...) by name, read and written in their units."""

from __future__ import annotations

from typing import Any

import click

from snakebot.cli.options import ControllerLink, controller_options
from snakebot.cli.output import dumps
from snakebot.link.controller.config import configure


def _print(rows: list[dict[str, Any]]) -> None:
    width = max(len(r["name"]) for r in rows)
    for r in rows:
        click.echo(f"{r['name']:<{width}}  {r['text']}")


@click.command("config", context_settings={"ignore_unknown_options": True})  # VALUE may be -10deg
@click.argument("action", required=False, type=click.Choice(["get", "set"]))
@click.argument("name", required=False)
@click.argument("value", required=False)
@controller_options
def config(
    action: str | None,
    name: str | None,
    value: str | None,
    link: ControllerLink,
    as_json: bool,
) -> None:
    """Show or change the controller's settings.

    \b
        snakebot config --port /dev/ttyUSB0                       # every setting
        snakebot config --port /dev/ttyUSB0 get safe-action
        snakebot config --port /dev/ttyUSB0 set link-timeout 1.5s
        snakebot config --port /dev/ttyUSB0 set safe-action HOLD

    NAME is a setting's name in any case, with '-', '_' or spaces. VALUE is a whole
    number (raw), an amount with a unit (1.5s, 10deg, 0.5rad, 2x) converted through the
    setting's scale, or one of the setting's value names. A value outside the setting's
    range is refused before anything is sent; after a set the value is read back.
    Settings live in the controller's RAM: a power cycle restores the defaults.
    """
    if action is None and name is not None:
        raise click.UsageError("give get NAME or set NAME VALUE (or nothing to list all)")
    if action == "get" and (name is None or value is not None):
        raise click.UsageError("get takes one NAME: snakebot config get NAME")
    if action == "set" and (name is None or value is None):
        raise click.UsageError("set takes NAME and VALUE: snakebot config set NAME VALUE")
    with link.open() as ctl:
        rows = configure(ctl, name, value if action == "set" else None)
    if as_json:
        click.echo(dumps(rows[0] if name is not None else rows))
    else:
        _print(rows)
