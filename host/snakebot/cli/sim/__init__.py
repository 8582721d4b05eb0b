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

import click

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli.options import (
    ideal_option,
    json_option,
    link_option,
    robot_option,
    world_option,
)
from snakebot.cli.output import dumps
from snakebot.cli.params import NUMBER
from snakebot.cli.signals import StopRequest, serving
from snakebot.sim.bus.bus import Bus
from snakebot.sim.errors import SimOptionError
from snakebot.sim.options import SimOptions, sim_query
from snakebot.sim.physics.select import DEFAULT_WORLD
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


@sim.command("bus")
@robot_option("Robot whose servos to emulate, with their IDs and zero ticks")
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
@link_option
@click.option("--servo-baud", type=NUMBER, help="The servos' baud rate, bit/s (default 1000000).")
@click.option(
    "--return-delay",
    type=NUMBER,
    help="The servos' Return Delay Time in microseconds (factory: 500).",
)
@click.option("--echo", is_flag=True, help="Echo every instruction back (one-wire adapter).")
@ideal_option
@click.option("--voltage", type=NUMBER, help="Supply voltage in volts (default 12).")
@click.option("--state", metavar="FILE", help="Keep the servos' EEPROM in FILE between runs.")
@world_option(note="On mujoco the body moves the servos (needs --robot).")
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
@json_option("one line: the device, the servo IDs, their model and the equivalent URL")
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
    query = sim_query(
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
        server: PtyServer | UnixSocketServer = UnixSocketServer(the_bus, unix_path, connect=connect)
    else:
        server = PtyServer(the_bus, link=link)
    with serving() as stop:
        try:
            _serve_bus(server, the_bus, query, robot, link, as_json, stop)
        finally:
            server.close()
    stop.exit_by_signal()


def _serve_bus(
    server: PtyServer | UnixSocketServer,
    the_bus: Bus,
    query: str,
    robot: str | None,
    link: str | None,
    as_json: bool,
    stop: StopRequest,
) -> None:
    """Start ``server``, say where it serves, and serve until ``stop``."""
    server.start()
    unix = isinstance(server, UnixSocketServer)
    where = str(server.path) if unix else server.device
    servos = [s.id for s in the_bus.servos]
    url = "sim://" + (f"?{query}" if query else "")
    if as_json:
        click.echo(
            dumps(
                {
                    "transport": "unix" if unix else "pty",
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
