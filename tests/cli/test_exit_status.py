"""The exit status follows the error's class (snakebot.cli.errors): bad input 2, runtime
failure 1, OSError 1, Ctrl-C 130, anything else an internal error, 1; and an error that
names its parameter gets the running command's option in front of its message."""

from __future__ import annotations

import click
import pytest
from click.testing import CliRunner

from snakebot.cli.errors import INTERNAL_ERROR, SnakebotGroup, exit_status
from snakebot.errors import InputError, RuntimeFailure, SnakebotError
from snakebot.formats.protocol.errors import DxlTimeout, PacketArgumentError
from snakebot.link.controller.errors import (
    ControllerStateError,
    LibraryRefused,
    UploadFailed,
    UploadRefused,
)
from snakebot.link.flash.errors import FlashFailed, ImageError
from snakebot.sim.errors import SimFailure, SimOptionError


@pytest.mark.parametrize(
    "exc, status",
    [
        (InputError("x"), 2),
        (PacketArgumentError("x"), 2),
        (UploadRefused("x"), 2),
        (LibraryRefused("x"), 2),
        (ImageError("x"), 2),
        (SimOptionError("x"), 2),
        (RuntimeFailure("x"), 1),
        (DxlTimeout("x"), 1),
        (UploadFailed("x"), 1),
        (ControllerStateError("x"), 1),
        (FlashFailed("x"), 1),
        (SimFailure("x"), 1),
        (OSError("x"), 1),
        (KeyboardInterrupt(), 130),
        (ValueError("x"), 1),
    ],
    ids=lambda v: type(v).__name__ if isinstance(v, BaseException) else str(v),
)
def test_exit_status_follows_the_class(exc, status):
    assert exit_status(exc) == status


@click.group(cls=SnakebotGroup)
def group() -> None:
    pass


@group.command("go")
@click.option("--rate", "rate_hz", type=float, default=1.0)
@click.option("--kind", default="a")
def go(rate_hz: float, kind: str) -> None:
    if kind == "input":
        raise InputError(f"the frame rate must be positive, not {rate_hz}").about("rate_hz")
    if kind == "elsewhere":
        raise InputError("a value is wrong").about("not_an_option_here")
    if kind == "runtime":
        raise RuntimeFailure("the controller did not answer")
    if kind == "unclassified":
        raise SnakebotError("under neither base")
    raise OSError("disk full")


@pytest.mark.parametrize(
    "kind, status, line",
    [
        ("input", 2, "error: --rate: the frame rate must be positive, not -1.0\n"),
        ("elsewhere", 2, "error: a value is wrong\n"),
        ("runtime", 1, "error: the controller did not answer\n"),
        ("a", 1, "error: disk full\n"),
    ],
)
def test_the_cli_prints_one_line_with_the_option_and_exits_by_class(kind, status, line):
    result = CliRunner().invoke(group, ["go", "--rate", "-1", "--kind", kind])
    assert (result.exit_code, result.output) == (status, line)


def test_an_error_under_neither_base_is_an_internal_error():
    result = CliRunner().invoke(group, ["go", "--kind", "unclassified"])
    assert result.exit_code == 1
    assert result.output.startswith(f"error: {INTERNAL_ERROR} (SnakebotError: under neither")
