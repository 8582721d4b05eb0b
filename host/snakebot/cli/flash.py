"""`snakebot flash`: put a firmware image on the CM-530 through the ROBOTIS bootloader."""

from __future__ import annotations

import sys
from typing import Any, TextIO

import click

from snakebot.cli.options import BOOTLOADER_PORT, json_option, port_option
from snakebot.cli.output import dumps
from snakebot.cli.params import INPUT_TEXT_PATH, NumberType
from snakebot.facts.boards import PC_LINK_BAUD
from snakebot.firmware import image as firmware_image
from snakebot.link.flash import FlashTimeouts, board_layout, flash, load_image
from snakebot.link.flash.bootloader import RESET_HINT, last_line
from snakebot.link.flash.errors import FlashFailed
from snakebot.link.flash.library_backup import backup_library, restore_library
from snakebot.link.flash.verify import flash_summary, verify_flashed
from snakebot.link.transport import open_port


class _LazyBar:
    """A progress bar that appears with the first image byte, not before the reset prompt."""

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


def _interactive() -> bool:
    """Whether someone at a terminal can answer a question."""
    return sys.stdin.isatty()


def _confirm_unverified(warning: str, yes: bool, out: TextIO) -> bool:
    """Whether to start firmware whose checksum report could not be read: --yes says so,
    else the user is asked; with nobody to ask, it is an error naming --yes."""
    click.echo(f"warning: {warning}", file=out)
    if yes:
        return True
    if not _interactive():
        raise FlashFailed(
            f"{warning}; the application was NOT started and nobody is at the terminal to "
            f"confirm: run again with --yes to start it anyway, or {RESET_HINT} and flash again"
        )
    return click.confirm("Start the new firmware anyway?", default=False, err=out is sys.stderr)


@click.command("flash")
@click.argument("firmware", required=False, type=INPUT_TEXT_PATH)
@port_option(BOOTLOADER_PORT)
@click.option(
    "--no-go",
    is_flag=True,
    help="Leave the board in the bootloader after a verified upload instead of "
    "starting the new firmware (send GO later, or press MODE or power-cycle the CM-530).",
)
@click.option(
    "--no-verify",
    is_flag=True,
    help="After GO, do not wait for the new firmware to answer and check its image "
    "(for firmware that is not snakebot's, or a board whose PC link is elsewhere).",
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
    help="How long to wait for you to reset the board (press MODE or power-cycle it; "
    "default 20, or SNAKEBOT_FLASH_RESET_TIMEOUT_S).",
)
@click.option(
    "--force",
    is_flag=True,
    help="Flash even if the image does not look like snakebot firmware for the CM-530 "
    "linked at 0x08003000 (vector table, board name and length in its identity block).",
)
@click.option(
    "--yes",
    "-y",
    is_flag=True,
    help="Start the new firmware without asking when the bootloader's checksum report is "
    "in a format snakebot does not know (it is then not verified).",
)
@click.option(
    "--no-library-backup",
    is_flag=True,
    help="Do not back the controller's gait library up before flashing (and restore it "
    "after): by default every stored slot is saved to a file first, in case the "
    "bootloader erases it.",
)
@json_option()
def flash_command(
    firmware: str | None,
    port: str,
    no_go: bool,
    no_verify: bool,
    no_checksum_byte: bool,
    reset_timeout: float | None,
    force: bool,
    yes: bool,
    no_library_backup: bool,
    as_json: bool,
) -> None:
    """Flash FIRMWARE (a .bin, .hex or .elf) onto the CM-530 through its ROBOTIS bootloader.

    Without FIRMWARE it flashes snakebot's own controller firmware: the image `make
    firmware` built in this checkout, else the one shipped with the installed package.

    Run the command, then press MODE on the CM-530 or power-cycle it when asked (it has no
    RESET button): the bootloader only listens for a moment after a reset. The command
    then loads the image, checks the bootloader's checksum against its own, starts the
    new firmware, and verifies it: it must answer PING at ID 200 with the model number
    and the firmware version of the image, and compute the same CRC-32 over its own image
    in flash as over the bytes sent (--no-verify skips this). A checksum report it cannot
    read is shown, and you are asked whether to start the firmware anyway (--yes: start
    it without asking).

    \b
        snakebot flash --port /dev/ttyUSB0
        snakebot flash build/cm530/firmware.bin --port /dev/ttyUSB0
        snakebot flash build/cm530/firmware.elf --port /dev/ttyUSB0

    Before asking for RESET, the gait library stored in the running controller (`snakebot
    library`) is saved to a file (its path is printed) and, once the new firmware
    answers, written back where the flashing lost it; a controller that does not answer
    is skipped with a warning.

    The link runs at 57600 baud, so 100 KB takes about 18 s. Timeouts can be raised with
    the SNAKEBOT_FLASH_*_S environment variables (see snakebot.link.flash.settings). A .hex or
    .elf is turned into the raw bytes the bootloader takes (the .elf's loadable segments at
    their load addresses), and refused if it puts anything outside the application area.
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
                confirm=lambda warning: _confirm_unverified(warning, yes, out),
            )
    finally:
        bar.close()
    say(f"Wrote {result.bytes_sent} bytes in {result.seconds:.2f} s ({result.kbit_s:.1f} kbit/s)")
    if result.reported_checksum is None:
        say("Checksum NOT verified (a report in an unknown format, accepted)")
    else:
        say(f"Checksum verified (0x{result.reported_checksum:02X}, {result.checksum_meaning})")
    if result.started:
        said = last_line(result.go_reply)
        say(f"Sent GO: the new firmware is starting (the bootloader said: {said})")
    else:
        say(f"Left the board in the bootloader (--no-go): send GO to start it, or {RESET_HINT}.")
    verified = None
    if result.started and not no_verify:
        verified = verify_flashed(port, image, layout.app_base, timeouts, say)
    if saved is not None and result.started:
        restore_library(port, saved, say, warn)
    elif saved is not None:
        say(f"Once it runs: `snakebot library restore {saved} --port {port}`")
    if as_json:
        click.echo(dumps(flash_summary(firmware, port, result, verified)), file=sys.stdout)
