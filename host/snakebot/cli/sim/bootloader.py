"""`snakebot sim bootloader`: an emulated ROBOTIS CM-530 bootloader on a pseudo-terminal,
to try `snakebot flash` (or RoboPlus-style terminal sessions) without a board."""

from __future__ import annotations

from typing import TYPE_CHECKING

import click

from snakebot.cli.errors import EXIT_BAD_INPUT, message
from snakebot.cli.options import json_option, link_option
from snakebot.cli.output import dumps
from snakebot.cli.params import NumberType
from snakebot.cli.signals import StopRequest, serving
from snakebot.cli.troubleshooting import error_line
from snakebot.errors import InputError, SnakebotError
from snakebot.sim.bootloader import (
    CHECKSUM_FORMATS,
    DEFAULT_SILENCE_S,
    PC_LINK_BAUD,
    Bootloader,
    BootloaderFaults,
    BootloaderPty,
    QemuHandover,
)

if TYPE_CHECKING:
    from snakebot.sim.mcu.handover import McuHandover


@click.command("bootloader")
@click.option(
    "--pty",
    "use_pty",
    is_flag=True,
    default=True,
    help="Serve on a new pseudo-terminal and print its device path (the default "
    "and only transport).",
)
@link_option
@click.option(
    "--reset-after",
    type=NumberType(0),
    metavar="SECONDS",
    help="Stay silent (running the application) for SECONDS, then reset, as when "
    "you press MODE on the CM-530 or power-cycle it; default: reset at once.",
)
@click.option(
    "--silence",
    type=NumberType(0.001),
    default=DEFAULT_SILENCE_S,
    show_default=True,
    metavar="SECONDS",
    help="Silence that ends an image being loaded.",
)
@click.option(
    "--no-pace", is_flag=True, help="Take bytes as fast as they come instead of at 57600 baud."
)
@click.option(
    "--sum-excludes-last",
    is_flag=True,
    help="Report the sum of all received bytes but the last (the checksum byte).",
)
@click.option(
    "--checksum-format",
    type=click.Choice(list(CHECKSUM_FORMATS)),
    default="hex8",
    show_default=True,
    help="How the Checksum line is printed: the sum's width (8/16/32 bits) and base; "
    "'unknown' prints no number.",
)
@click.option("--mute", is_flag=True, help="Fault: never answer '#'.")
@click.option("--no-ready", is_flag=True, help="Fault: never answer the load command.")
@click.option(
    "--corrupt",
    is_flag=True,
    help="Fault: flip one bit of each stored image (the checksum will not match).",
)
@click.option(
    "--drop-every",
    type=click.IntRange(0),
    default=0,
    metavar="N",
    help="Fault: lose every Nth image byte on the way in (0: none).",
)
@click.option(
    "--reset-during-transfer",
    type=click.IntRange(1),
    metavar="BYTES",
    help="Fault: reset the board once BYTES image bytes have arrived.",
)
@click.option(
    "--qemu",
    is_flag=True,
    help="After GO, run the stored image in QEMU (the qemu board: build it with make "
    "firmware, flash build/qemu/firmware.bin --force) and pass the line to it, instead of "
    "on the emulated CM-530.",
)
@json_option("one with the device, then one per image received, on exit")
def bootloader(
    use_pty: bool,
    link: str | None,
    reset_after: float | None,
    silence: float,
    no_pace: bool,
    sum_excludes_last: bool,
    checksum_format: str,
    mute: bool,
    no_ready: bool,
    corrupt: bool,
    drop_every: int,
    reset_during_transfer: int | None,
    qemu: bool,
    as_json: bool,
) -> None:
    """Serve an emulated CM-530 bootloader until interrupted (Ctrl-C).

    It answers '#' with a banner and a prompt, then takes the commands L (load), GO,
    G ADDR, APP, SYS and help, at 57600 baud. Try it with

    \b
        snakebot sim bootloader --link /tmp/ttyCM530
        snakebot flash build/cm530/firmware.bin --port /tmp/ttyCM530   # another shell

    After GO the image it received starts on the emulated CM-530 (the STM32F103RE of
    `snakebot sim serve --board cm530`) and the line is passed to it, so the flasher's
    check of the new firmware runs against the image it sent. An image the board could not
    start (another board's, empty, cut short, a reset vector outside it) behaves as on the
    board: nothing answers on the line any more, so the flasher's check fails. The server
    prints at once one line saying what is wrong with the image, keeps the line open
    (dropping what comes), and exits with status 2 once the flasher has closed the line.
    On exit it lists the images it received, with their sizes and checksums.
    """
    boot = Bootloader(
        faults=BootloaderFaults(
            mute=mute,
            no_ready=no_ready,
            corrupt=corrupt,
            drop_every=drop_every,
            reset_after=reset_during_transfer,
        ),
        silence_s=silence,
        sum_excludes_last=sum_excludes_last,
        checksum_format=checksum_format,
    )
    if qemu:
        handover: QemuHandover | McuHandover = QemuHandover()
    else:
        from snakebot.sim.mcu.handover import McuHandover  # needs unicorn (the mcu extra)

        handover = McuHandover()
    server = BootloaderPty(
        boot, reset_after_s=reset_after, pace=not no_pace, link=link, on_go=handover
    )
    with serving() as stop:
        try:
            not_started = _serve(server, link, as_json, stop)
        finally:
            server.close()
            handover.close()
    _list_images(server, checksum_format, sum_excludes_last, as_json)
    stop.exit_by_signal()
    if not_started is not None:  # told already, when it happened: only the status is left
        click.get_current_context().exit(EXIT_BAD_INPUT)


def _serve(
    server: BootloaderPty, link: str | None, as_json: bool, stop: StopRequest
) -> InputError | None:
    """Start ``server``, say where it serves, and serve until ``stop``, or until the client
    lets go of a board that could not start the image it received; returns why it could
    not (said on stderr as soon as it happened), or None."""
    server.start()
    _say_where(server, link, as_json)
    told = False
    while not stop.wait(0.2):
        told = told or _tell_not_started(server)
        if not server.running:
            if server.not_started is not None:
                break
            if isinstance(server.error, SnakebotError):
                raise server.error
            raise click.ClickException(f"the bootloader server stopped: {server.error}")
    if not told:
        _tell_not_started(server)
    return server.not_started


def _tell_not_started(server: BootloaderPty) -> bool:
    """Print, as the CLI prints an error, why the board could not start the image it
    received; whether there was something to tell."""
    if server.not_started is None:
        return False
    click.echo(error_line(message(server.not_started)), err=True)
    return True


def _say_where(server: BootloaderPty, link: str | None, as_json: bool) -> None:
    """The device (and link) the bootloader serves on, and how to stop it."""
    if as_json:
        click.echo(dumps({"device": server.device, "link": link, "baud": PC_LINK_BAUD}))
    else:
        click.echo(
            f"emulated CM-530 bootloader on {server.device}"
            + (f" (link {link})" if link else "")
            + f", {PC_LINK_BAUD} baud"
        )
        click.echo("Ctrl-C stops.")


def _list_images(
    server: BootloaderPty, checksum_format: str, excludes_last: bool, as_json: bool
) -> None:
    """One line per image received, with its size and the checksum it was reported as."""
    boot = server.bootloader
    with server.lock:
        images = list(boot.images)
    bits = CHECKSUM_FORMATS[checksum_format][1]
    for n, image in enumerate(images, 1):
        total = boot.reported_sum(image, excludes_last, bits)
        if as_json:
            click.echo(dumps({"image": n, "bytes": len(image), "checksum": total}))
        else:
            click.echo(f"image {n}: {len(image)} bytes, checksum 0x{total:0{bits // 4}X}")
