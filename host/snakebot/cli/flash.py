"""`snakebot flash`: put a firmware image on the CM-530 through the ROBOTIS bootloader."""

from __future__ import annotations

import sys
from typing import Any, TextIO

import click

from snakebot.cli.output import dumps
from snakebot.cli.params import NumberType, controller_port
from snakebot.firmware import image as firmware_image
from snakebot.flash import PC_LINK_BAUD, FlashTimeouts, board_layout, flash, load_image
from snakebot.flash.library_backup import backup_library, restore_library
from snakebot.flash.loader import last_line
from snakebot.transport import open_port


class _LazyBar:
    """A progress bar that appears with the first image byte, not before the RESET prompt."""

    def __init__(self, length: int, out: TextIO) -> None:
        self.length = length
        self.out = out
        self._bar: Any = None

    def update(self, n: int) -> None:
        if self._bar is None:
            self._bar = click.progressbar(
                length=self.length, label="Writing", file=self.out, show_pos=True
            )
            self._bar.__enter__()
        self._bar.update(n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.__exit__(None, None, None)
            self._bar = None


@click.command("flash")
@click.argument("firmware", required=False, type=click.Path(dir_okay=False, path_type=str))
@click.option(
    "--port",
    "-p",
    required=True,
    envvar="SNAKEBOT_PORT",
    show_envvar=True,
    callback=controller_port("snakebot sim bootloader"),
    help="The CM-530's PC link: its USB-serial device (/dev/ttyUSB0, COM3), a pyserial URL, "
    "or the pseudo-terminal of `snakebot sim bootloader`.",
)
@click.option(
    "--no-go",
    is_flag=True,
    help="Leave the board in the bootloader after a verified upload instead of "
    "starting the new firmware (send GO later, or press RESET).",
)
@click.option(
    "--no-checksum-byte",
    is_flag=True,
    help="Send only the image, without the trailing checksum byte that RoboPlus "
    "Terminal appends (the low byte of the sum of the image's bytes).",
)
@click.option(
    "--reset-timeout",
    type=NumberType(0.1),
    metavar="SECONDS",
    help="How long to wait for you to press RESET (default 20, or SNAKEBOT_FLASH_RESET_TIMEOUT_S).",
)
@click.option(
    "--force",
    is_flag=True,
    help="Flash even if the image does not look like snakebot firmware for the CM-530 "
    "linked at 0x08003000 (vector table, board name and length in its identity block).",
)
@click.option(
    "--no-library-backup",
    is_flag=True,
    help="Do not back the controller's gait library up before flashing (and restore it "
    "after): by default every stored slot is saved to a file first, in case the "
    "bootloader erases it.",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the result as one JSON object on stdout (messages go to stderr).",
)
def flash_command(
    firmware: str | None,
    port: str,
    no_go: bool,
    no_checksum_byte: bool,
    reset_timeout: float | None,
    force: bool,
    no_library_backup: bool,
    as_json: bool,
) -> None:
    """Flash FIRMWARE (a raw .bin) onto the CM-530 through its ROBOTIS bootloader.

    Without FIRMWARE it flashes snakebot's own controller firmware: the image `make
    firmware` built in this checkout, else the one shipped with the installed package.

    Run the command, then press RESET on the CM-530 (or switch it on) when asked: the
    bootloader only listens for a moment after a reset. The command then loads the image,
    checks the bootloader's checksum against its own, and starts the new firmware.

    \b
        snakebot flash --port /dev/ttyUSB0
        snakebot flash build/cm530/firmware.bin --port /dev/ttyUSB0

    Before asking for RESET, the gait library stored in the running controller (`snakebot
    library`) is saved to a file (its path is printed) and, once the new firmware
    answers, written back where the flashing lost it; a controller that does not answer
    is skipped with a warning.

    The link runs at 57600 baud, so 100 KB takes about 18 s. Timeouts can be raised with
    the SNAKEBOT_FLASH_*_S environment variables (see snakebot.flash.settings). Give the
    .bin, not the .hex or .elf: the bootloader takes raw bytes.
    """
    out = sys.stderr if as_json else sys.stdout

    def say(message: str) -> None:
        click.echo(message, file=out)

    def warn(message: str) -> None:
        click.echo(message, err=True)

    if firmware is None:
        firmware = str(firmware_image("cm530", "firmware.bin"))
    layout = board_layout()
    image = load_image(firmware, layout, check_vectors=not force)
    timeouts = FlashTimeouts.resolve(reset=reset_timeout)
    say(
        f"Flashing {firmware} ({len(image)} bytes, {len(image) * 100 / layout.app_size:.1f}% "
        f"of the {layout.app_size // 1024} KB application area) via {port} at "
        f"{PC_LINK_BAUD} baud."
    )
    saved = None if no_library_backup else backup_library(port, say, warn)
    bar = _LazyBar(len(image) + (0 if no_checksum_byte else 1), out)
    try:
        with open_port(port, PC_LINK_BAUD, timeout=0) as link:
            result = flash(
                link,
                image,
                checksum_byte=not no_checksum_byte,
                go=not no_go,
                timeouts=timeouts,
                say=say,
                progress=bar.update,
            )
    finally:
        bar.close()
    say(f"Wrote {result.bytes_sent} bytes in {result.seconds:.2f} s ({result.kbit_s:.1f} kbit/s)")
    say(f"Checksum verified (0x{result.reported_checksum:02X}, {result.checksum_meaning})")
    if result.started:
        said = last_line(result.go_reply)
        say(f"Sent GO: the new firmware is starting (the bootloader said: {said})")
    else:
        say("Left the board in the bootloader (--no-go): press RESET or send GO to start it.")
    if saved is not None and result.started:
        restore_library(port, saved, say, warn)
    elif saved is not None:
        say(f"Once it runs: `snakebot library restore {saved} --port {port}`")
    if as_json:
        click.echo(
            dumps(
                {
                    "firmware": firmware,
                    "port": port,
                    "image_bytes": result.image_size,
                    "bytes_sent": result.bytes_sent,
                    "checksum_byte": result.checksum_byte,
                    "checksum": result.reported_checksum,
                    "checksum_meaning": result.checksum_meaning,
                    "seconds": round(result.seconds, 4),
                    "send_seconds": round(result.send_seconds, 4),
                    "kbit_s": round(result.kbit_s, 2),
                    "started": result.started,
                    "banner": result.banner.decode("latin-1"),
                    "go_reply": result.go_reply.decode("latin-1"),
                }
            ),
            file=sys.stdout,
        )
