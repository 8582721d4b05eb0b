"""Commands loaded when they are run: ``snakebot --help`` and a command's own run import
only what that command needs (its module, and the library it calls), not every command
and numpy, matplotlib, MuJoCo and the ELF reader behind them.

A :class:`LazyGroup` knows each command by its module and attribute, and by its one-line
help for the group's listing, so listing the commands imports none of them;
``tests/cli/test_startup.py`` holds each line to the command's own docstring.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

import click

from snakebot.cli.errors import SnakebotGroup

FULL_LINE = 1000
"""A length no one-line help reaches: the line whole, ready to be shortened."""


@dataclass(frozen=True)
class LazyCommand:
    """Where a command lives (``module:attribute``), the one-line help the group lists,
    and the sub-commands to attach to it when it is a group (``module:attribute`` each)."""

    where: str
    short_help: str
    subcommands: tuple[str, ...] = ()


def load(where: str) -> click.Command:
    """The command at ``module:attribute``."""
    module, attribute = where.split(":")
    command = getattr(importlib.import_module(module), attribute)
    if not isinstance(command, click.Command):
        raise TypeError(f"{where} is not a click command")
    return command


class LazyGroup(SnakebotGroup):
    """A group whose commands (``lazy``: name -> :class:`LazyCommand`) are imported the
    first time they are asked for."""

    def __init__(self, *args: object, lazy: dict[str, LazyCommand], **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.lazy = lazy

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted({*super().list_commands(ctx), *self.lazy})

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in self.commands and cmd_name in self.lazy:
            entry = self.lazy[cmd_name]
            command = load(entry.where)
            if isinstance(command, click.Group):
                for where in entry.subcommands:
                    command.add_command(load(where))
            self.add_command(command, cmd_name)
        return super().get_command(ctx, cmd_name)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """Click's listing, its lines from the table: no command is imported to list it."""
        names = [
            n for n in self.list_commands(ctx) if n in self.lazy or not self.commands[n].hidden
        ]
        if not names:
            return
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = []
        for name in names:
            if name in self.commands:
                rows.append((name, self.commands[name].get_short_help_str(limit)))
            else:
                line = click.Command(name, help=self.lazy[name].short_help)
                rows.append((name, line.get_short_help_str(limit)))
        with formatter.section("Commands"):
            formatter.write_dl(rows)


def short_help(command: click.Command) -> str:
    """A command's line in its group's listing, before it is shortened to fit: what a
    :class:`LazyCommand` holds."""
    return command.get_short_help_str(FULL_LINE)
