"""The one place where exceptions become a one-line message and an exit status.

Exit statuses (the same for every command):

* 0: done;
* 1: a runtime failure, the input was fine: a controller or servo that does not answer,
  an upload that did not land, a file that cannot be written (OSError);
* 2: bad input: a usage error (click's), a value out of range, a malformed file, a port
  that does not exist;
* 130: interrupted with Ctrl-C (SIGINT); 143 with SIGTERM, 129 with SIGHUP (see
  ``snakebot.cli.signals``: the same clean stop for all three);
* 141: stdout was closed early (``snakebot ... | head``): nothing more is printed.

Library errors (``SnakebotError``) carry a message that names the problem and the fix;
operating-system errors (pyserial's ``SerialException`` is an ``OSError``) get their
sentence too. Anything else is a bug in snakebot: it is reported as one line that says
so (the traceback is shown with ``SNAKEBOT_DEBUG=1``), never as a traceback.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from typing import Any

import click

from snakebot.cli.signals import install as install_signal_handlers
from snakebot.cli.signals import interrupted_status
from snakebot.errors import SnakebotError
from snakebot.formats.protocol.errors import CorruptPacket, DxlTimeout, ServoError
from snakebot.link.controller.errors import ControllerLinkError, UploadError
from snakebot.link.flash.errors import FlashError, FlashSettingError, ImageError
from snakebot.settings import check_environment, is_set
from snakebot.sim.errors import SimOptionError

EXIT_RUNTIME = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141
EXIT_FAILURE = EXIT_BAD_INPUT  # the status of a SnakebotError that is not a runtime failure

INTERNAL_ERROR = "internal error"
"""Starts the message of an exception that is a bug; tests look for it."""

DEBUG_ENV = "SNAKEBOT_DEBUG"

RUNTIME_ERRORS: tuple[type[BaseException], ...] = (
    DxlTimeout,
    CorruptPacket,
    ServoError,
    ControllerLinkError,
    UploadError,
    FlashError,
)
"""Library errors that mean "the input was fine, the world did not cooperate"."""

INPUT_ERRORS: tuple[type[BaseException], ...] = (ImageError, FlashSettingError, SimOptionError)
"""Subclasses of runtime errors that are about the input after all."""


def exit_status(exc: BaseException) -> int:
    """The exit status for ``exc`` (see the module docstring)."""
    if isinstance(exc, INPUT_ERRORS):
        return EXIT_BAD_INPUT
    if isinstance(exc, RUNTIME_ERRORS):
        return EXIT_RUNTIME
    if isinstance(exc, SnakebotError):
        return EXIT_BAD_INPUT
    return EXIT_RUNTIME


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
            click.echo(f"error: {_one_line(exc.format_message())}{hint}", err=True)
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
        except (SnakebotError, OSError) as exc:
            click.echo(f"error: {_one_line(str(exc) or type(exc).__name__)}", err=True)
            ctx.exit(exit_status(exc))
        except Exception as exc:  # a bug: say so in one line, never a traceback
            if is_set(DEBUG_ENV):
                raise
            click.echo(
                f"error: {INTERNAL_ERROR} ({type(exc).__name__}: {_one_line(str(exc))[:200]}); "
                f"please report it with the command line (run with {DEBUG_ENV}=1 for the "
                "traceback)",
                err=True,
            )
            ctx.exit(EXIT_RUNTIME)


def _one_line(text: str) -> str:
    return " ".join(text.split())
