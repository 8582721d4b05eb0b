"""`snakebot sim bootloader`: an emulated ROBOTIS CM-530 bootloader on a pseudo-terminal,
to try `snakebot flash` (or RoboPlus-style terminal sessions) without a board."""

from __future__ import annotations

import signal
import threading
from types import FrameType

import click

from snakebot.cli.output import dumps
from snakebot.cli.params import NumberType
from snakebot.cli.signals import STOP_SIGNALS
from snakebot.sim.bootloader import (
    CHECKSUM_FORMATS,
    DEFAULT_SILENCE_S,
    PC_LINK_BAUD,
    Bootloader,
    BootloaderFaults,
    BootloaderPty,
    QemuHandover,
)


@click.command("bootloader")
@click.option(
    "--pty",
    "use_pty",
    is_flag=True,
    default=True,
    help="Serve on a new pseudo-terminal and print its device path (the default "
    "and only transport).",
)
@click.option(
    "--link", metavar="PATH", help="Also create a symlink PATH to the device, e.g. /tmp/ttyCM530."
)
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
    "firmware, flash build/qemu/firmware.bin --force) and pass the line to it.",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print one JSON line with the device, then one per image on exit.",
)
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
    handover = QemuHandover() if qemu else None
    server = BootloaderPty(
        boot, reset_after_s=reset_after, pace=not no_pace, link=link, on_go=handover
    ).start()
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in STOP_SIGNALS}
    try:
        if as_json:
            click.echo(dumps({"device": server.device, "link": link, "baud": PC_LINK_BAUD}))
        else:
            click.echo(
                f"emulated CM-530 bootloader on {server.device}"
                + (f" (link {link})" if link else "")
                + f", {PC_LINK_BAUD} baud"
            )
            click.echo("Ctrl-C stops.")
        while not stop.wait(0.2):
            if not server.running:
                raise click.ClickException(f"the bootloader server stopped: {server.error}")
    finally:
        server.close()
        if handover is not None:
            handover.close()
        for s, handler in previous.items():
            signal.signal(s, handler)
    with server.lock:
        images = list(boot.images)
    for n, image in enumerate(images, 1):
        bits = CHECKSUM_FORMATS[checksum_format][1]
        total = boot.reported_sum(image, sum_excludes_last, bits)
        if as_json:
            click.echo(dumps({"image": n, "bytes": len(image), "checksum": total}))
        else:
            click.echo(f"image {n}: {len(image)} bytes, checksum 0x{total:0{bits // 4}X}")
