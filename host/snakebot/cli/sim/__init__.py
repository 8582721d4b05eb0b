"""`snakebot sim`: the emulated robot.

`sim bus` (here) serves an emulated Dynamixel bus of virtual AX-12 servos to other
programs, on a pseudo-terminal (any serial client: snakebot, ROBOTIS's dynamixel-sdk, a
terminal) or on a Unix socket (QEMU's USART). In-process clients need no server: give
them the port `sim://?robot=snake5` (options as in the URL this command prints). The
other subcommands each have a module: ``serve`` (the firmware in QEMU behind a
pseudo-terminal), ``bootloader``, ``predict``, ``goto``, ``thesis`` (with ``friction``).

May import: as the ``cli`` layer (every layer below it).
"""

from __future__ import annotations

import signal
import threading
from types import FrameType
from urllib.parse import urlencode

import click

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli.output import dumps
from snakebot.cli.params import NUMBER
from snakebot.cli.signals import STOP_SIGNALS
from snakebot.sim.errors import SimOptionError
from snakebot.sim.options import SimOptions
from snakebot.sim.physics.select import DEFAULT_WORLD, WORLDS
from snakebot.sim.transports import PtyServer, UnixSocketServer


@click.group()
def sim() -> None:
    """The emulated robot: virtual AX-12 servos on an emulated bus.

    The bus commands (`snakebot bus ...`) also accept --port sim://?robot=snake5 (add
    &echo=1, &corrupt=0.01, ... as listed in `snakebot sim bus --help`) to run against
    emulated servos in process, with no server. The controller commands (upload, play,
    stop, serpenoid, monitor) need a controller: `snakebot sim serve` runs the firmware
    and prints the port to give them; `snakebot sim bootloader` does the same for flash.
    """


def _query(**flags: object) -> str:
    pairs: list[tuple[str, str]] = []
    for key, value in flags.items():
        if value is None or value is False or value == ():
            continue
        if key == "brownout":
            pairs += [("brownout", v) for v in value]  # type: ignore[union-attr]
        elif value is True:
            pairs.append((key, "1"))
        else:
            pairs.append((key, str(value)))
    return urlencode(pairs, safe=",@+;/")


@sim.command("bus")
@click.option(
    "--robot",
    "-r",
    help="Robot whose servos to emulate: snake3, trident, snake5 or "
    "a robot TOML file (servo IDs and zero ticks come from it).",
)
@click.option("--ids", help="Servo IDs instead of a robot, e.g. 1,2,3 (default: one servo, ID 1).")
@click.option("--model", help="Servo model: AX-12A or AX-12W (default: the robot's).")
@click.option(
    "--pty",
    "transport",
    flag_value="pty",
    default=True,
    help="Serve on a new pseudo-terminal (default) and print its device path.",
)
@click.option(
    "--unix",
    "unix_path",
    metavar="PATH",
    help="Serve on a Unix socket at PATH instead, for QEMU (-serial unix:PATH,server=off).",
)
@click.option(
    "--connect",
    is_flag=True,
    help="With --unix: connect to a socket QEMU listens on instead of listening.",
)
@click.option(
    "--link",
    metavar="PATH",
    help="With --pty: also create a symlink PATH to the device, e.g. /tmp/ttyDXL.",
)
@click.option("--servo-baud", type=NUMBER, help="The servos' baud rate, bit/s (default 1000000).")
@click.option(
    "--return-delay",
    type=NUMBER,
    help="The servos' Return Delay Time in microseconds (factory: 500).",
)
@click.option("--echo", is_flag=True, help="Echo every instruction back (one-wire adapter).")
@click.option("--ideal", is_flag=True, help="Servos reach their goal instantly.")
@click.option("--voltage", type=NUMBER, help="Supply voltage in volts (default 12).")
@click.option("--state", metavar="FILE", help="Keep the servos' EEPROM in FILE between runs.")
@click.option(
    "--world",
    type=click.Choice(WORLDS),
    default=DEFAULT_WORLD,
    show_default=True,
    help="kinematic: each servo moves by its own model; mujoco: the robot's body in "
    "MuJoCo moves the servos (their position, speed and load come from the physics; "
    "needs --robot).",
)
@click.option("--seed", type=int, help="Seed for the injected faults (default 0).")
@click.option("--corrupt", type=NUMBER, help="Probability of a flipped bit per byte on the wire.")
@click.option("--drop", type=NUMBER, help="Probability that a status packet is lost.")
@click.option("--delay", type=NUMBER, help="Extra milliseconds before each status packet.")
@click.option("--jitter", type=NUMBER, help="Plus a random 0..JITTER milliseconds.")
@click.option("--noise", type=NUMBER, help="Noise bursts per second.")
@click.option("--noise-len", type=int, help="Longest noise burst in bytes (default 4).")
@click.option(
    "--brownout",
    multiple=True,
    metavar="ID@START+DUR",
    help="Servo ID loses power at START s for DUR s (repeatable).",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print one JSON line (device, servo IDs, model, equivalent URL).",
)
def bus(
    robot: str | None,
    ids: str | None,
    model: str | None,
    transport: str,
    unix_path: str | None,
    connect: bool,
    link: str | None,
    servo_baud: float | None,
    return_delay: float | None,
    echo: bool,
    ideal: bool,
    voltage: float | None,
    state: str | None,
    world: str,
    seed: int | None,
    corrupt: float | None,
    drop: float | None,
    delay: float | None,
    jitter: float | None,
    noise: float | None,
    noise_len: int | None,
    brownout: tuple[str, ...],
    as_json: bool,
) -> None:
    """Serve an emulated Dynamixel bus until interrupted (Ctrl-C).

    With --pty it prints the pseudo-terminal to give your client, e.g.

        snakebot sim bus --robot snake5 --pty

    then, in another shell, any Protocol 1.0 client at 1000000 baud on that device
    (the servos of snake5 answer at IDs 10, 11, 15, 16). Replies come in real time,
    with the wire timing of the servos' baud rate and Return Delay Time.
    """
    if connect and not unix_path:
        raise SimOptionError("--connect needs --unix PATH (it says how to reach QEMU's socket)")
    if link and unix_path:
        raise SimOptionError("--link is for --pty; with --unix the socket path is the link")
    query = _query(
        robot=robot,
        ids=ids,
        model=model,
        baud=servo_baud,
        return_delay=return_delay,
        echo=echo,
        ideal=ideal,
        voltage=voltage,
        state=state,
        world=None if world == DEFAULT_WORLD else world,
        seed=seed,
        corrupt=corrupt,
        drop=drop,
        delay=delay,
        jitter=jitter,
        noise=noise,
        noise_len=noise_len,
        brownout=brownout,
    )
    options = SimOptions.from_query(query)
    the_bus = options.build_bus()
    if unix_path:
        server: PtyServer | UnixSocketServer = UnixSocketServer(
            the_bus, unix_path, connect=connect
        ).start()
        where = str(server.path)
    else:
        server = PtyServer(the_bus, link=link).start()
        where = server.device
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in STOP_SIGNALS}
    try:
        servos = [s.id for s in the_bus.servos]
        url = "sim://" + (f"?{query}" if query else "")
        if as_json:
            click.echo(
                dumps(
                    {
                        "transport": "unix" if unix_path else "pty",
                        "device": where,
                        "link": link,
                        "ids": servos,
                        "model": the_bus.servos[0].model,
                        "url": url,
                    }
                )
            )
        else:
            what = f"{robot} " if robot else ""
            click.echo(
                f"emulated {what}bus: {len(servos)} {the_bus.servos[0].model} servo(s), "
                f"IDs {', '.join(map(str, servos))}"
            )
            click.echo(f"serving on {where}" + (f" (link {link})" if link else ""))
            click.echo(f"in process, the same emulation is {url}")
            click.echo("Ctrl-C stops.")
        while not stop.wait(0.2):
            if not server.running:
                raise click.ClickException("the bus server stopped unexpectedly")
    finally:
        server.close()
        for s, handler in previous.items():
            signal.signal(s, handler)
