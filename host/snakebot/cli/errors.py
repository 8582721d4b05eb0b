"""The one place where exceptions become a one-line message and an exit status.

Exit statuses (the same for every command):

* 0: done;
* 1: a runtime failure, the input was fine: a controller or servo that does not answer,
  an upload that did not land, a controller in the safe state, a file that cannot be
  written (OSError);
* 2: bad input: a usage error (click's), a value out of range, a malformed file, a table
  outside the robot's limits, a port that does not exist;
* 130: interrupted with Ctrl-C (SIGINT); 143 with SIGTERM, 129 with SIGHUP (see
  ``snakebot.cli.signals``: the same clean stop for all three);
* 141: stdout was closed early (``snakebot ... | head``): nothing more is printed.

The status follows the class, never a list: every library error is an
``snakebot.errors.InputError`` (2) or an ``snakebot.errors.RuntimeFailure`` (1); an
``OSError`` (pyserial's ``SerialException`` is one) is a runtime failure (1). Library
errors carry a message that names the problem and the fix; when one says which parameter
was at fault (``SnakebotError.about``), the message is prefixed with the running
command's option for it (``error: --rate: the frame rate must be ...``); an error that
``docs/troubleshooting.md`` explains carries its code there (``error[E101]: ...``,
``snakebot.cli.troubleshooting``). Anything else,
a ``SnakebotError`` under neither base included, is a bug in snakebot: it is reported
as one line that says so, status 1 (the traceback is shown with ``SNAKEBOT_DEBUG=1``),
never as a traceback.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from types import TracebackType
from typing import Any

import click

from snakebot.cli.signals import install as install_signal_handlers
from snakebot.cli.signals import interrupted_status
from snakebot.cli.troubleshooting import error_line
from snakebot.errors import InputError, RuntimeFailure, bounded_line
from snakebot.settings import check_environment, is_set

EXIT_RUNTIME = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141

INTERNAL_ERROR = "internal error"
"""Starts the message of an exception that is a bug; tests look for it."""

DEBUG_ENV = "SNAKEBOT_DEBUG"


def exit_status(exc: BaseException) -> int:
    """The exit status for ``exc``, by its class (see the module docstring)."""
    if isinstance(exc, KeyboardInterrupt):
        return EXIT_INTERRUPTED
    if isinstance(exc, InputError):
        return EXIT_BAD_INPUT
    return EXIT_RUNTIME  # RuntimeFailure, OSError, and bugs


def is_reported(exc: BaseException) -> bool:
    """Whether ``exc`` is printed as its own message (a classified library error or an
    OSError), not as an internal error."""
    return isinstance(exc, InputError | RuntimeFailure | OSError)


def _command_context(tb: TracebackType | None) -> click.Context | None:
    """The context of the innermost command the traceback ``tb`` ran through: the last
    ``click.Context.invoke`` frame's (the one that called the command's callback)."""
    found: click.Context | None = None
    code = click.Context.invoke.__code__
    while tb is not None:
        if tb.tb_frame.f_code is code:
            ctx = tb.tb_frame.f_locals.get("self")
            if isinstance(ctx, click.Context):
                found = ctx
        tb = tb.tb_next
    return found


def option_names(exc: BaseException, ctx: click.Context | None) -> list[str]:
    """The options of the command ``ctx`` that the parameters ``exc`` is about
    (``SnakebotError.about``) came through, e.g. ``["--rate"]``; none it does not have."""
    params = getattr(exc, "params", ())
    if not params or ctx is None:
        return []
    by_name = {p.name: p for p in ctx.command.params if isinstance(p, click.Option)}
    names = []
    for name in params:
        option = by_name.get(name)
        if option is not None and option.opts:
            names.append(max(option.opts, key=len))
    return names


def message(exc: BaseException, ctx: click.Context | None = None) -> str:
    """``exc``'s one-line message, led by the options it is about, if ``ctx``'s
    command has them."""
    text = _one_line(str(exc) or type(exc).__name__)
    options = option_names(exc, ctx)
    return f"{', '.join(options)}: {text}" if options else text


def _quiet_broken_pipe() -> None:
    # Python flushes stdout at exit and would report the broken pipe again; point it at
    # /dev/null so nothing more is written anywhere.
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass  # no real file descriptor (under a test runner): nothing will flush


class SnakebotGroup(click.Group):
    """A click group that turns every exception into ``error: ...`` and an exit status."""

    def main(  # type: ignore[override]
        self,
        args: Sequence[str] | None = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        **extra: Any,
    ) -> Any:
        """click's ``main``, with its usage errors in one line too:
        ``error: Invalid value for '--rate': ... (see `snakebot gait serpenoid --help`)``."""
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, **extra)
        install_signal_handlers()
        try:
            status = super().main(args, prog_name, complete_var, False, **extra)
        except click.exceptions.NoArgsIsHelpError as exc:
            click.echo(exc.format_message(), err=True)  # a group run bare: its help
            sys.exit(exc.exit_code)
        except click.ClickException as exc:
            hint = ""
            ctx = getattr(exc, "ctx", None)
            if isinstance(exc, click.UsageError) and ctx is not None:
                hint = f" (see `{ctx.command_path} --help`)"
            click.echo(error_line(_one_line(exc.format_message()), hint), err=True)
            sys.exit(exc.exit_code)
        except click.Abort as exc:
            click.echo("interrupted", err=True)
            sys.exit(interrupted_status(exc))
        except KeyboardInterrupt as exc:  # while click parsed, before a command ran
            click.echo("interrupted", err=True)
            sys.exit(interrupted_status(exc))
        sys.exit(status if isinstance(status, int) else 0)

    def invoke(self, ctx: click.Context) -> Any:
        try:
            if ctx.parent is None:
                check_environment()  # a bad SNAKEBOT_* value: one line, exit 2, no work done
            return super().invoke(ctx)
        except (click.exceptions.Exit, click.ClickException, click.Abort):
            raise  # click's own: usage errors (2) and explicit exits
        except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM, SIGHUP: the same clean stop
            click.echo("interrupted", err=True)
            ctx.exit(interrupted_status(exc))
        except BrokenPipeError:
            _quiet_broken_pipe()
            ctx.exit(EXIT_BROKEN_PIPE)
        except Exception as exc:
            if is_reported(exc):
                inner = _command_context(exc.__traceback__)
                click.echo(error_line(message(exc, inner)), err=True)
                ctx.exit(exit_status(exc))
            # a bug: say so in one line, never a traceback
            if is_set(DEBUG_ENV):
                raise
            click.echo(
                f"error: {INTERNAL_ERROR} ({type(exc).__name__}: "
                f"{bounded_line(_one_line(str(exc)), 200)}); "
                f"please report it with the command line (run with {DEBUG_ENV}=1 for the "
                "traceback)",
                err=True,
            )
            ctx.exit(EXIT_RUNTIME)


def _one_line(text: str) -> str:
    return " ".join(text.split())
