"""`snakebot bus`: servo chores on a Dynamixel bus through a direct adapter (USB2Dynamixel,
U2D2 in Protocol 1.0, or the emulator): scan, ping, read, write, set-id, set-baud
(here), and ``bus play`` (``play``). The work itself is in :mod:`snakebot.link.bus`.

May import: as the ``cli`` layer (every layer below it)."""

from __future__ import annotations

import contextlib
import functools
import sys
from collections.abc import Callable, Iterator
from typing import Any, NoReturn

import click

from snakebot.cli.errors import EXIT_RUNTIME
from snakebot.cli.output import dumps
from snakebot.cli.params import NumberType
from snakebot.formats import register_values
from snakebot.formats.register_values import BusCommandError
from snakebot.link.bus import ids as bus_ids
from snakebot.link.bus import registers as bus_registers
from snakebot.link.bus import scan as bus_scan
from snakebot.link.bus.scan import Probe, ServoInfo
from snakebot.link.transport import DEFAULT_BAUDRATE, DxlClient, open_port

EXIT_INTERRUPTED = 130
"""What a shell reports for a command stopped by Ctrl-C (128 + SIGINT)."""

PORT_HELP = (
    "The bus adapter: a device (/dev/ttyUSB0, COM3), a pyserial URL, or sim://?ids=1,2 for "
    "the emulator."
)


def _servo_baud(ctx: click.Context, param: click.Parameter, value: int) -> int:
    """--baud: a rate some described servo runs at."""
    try:
        register_values.check_bus_baud(value)
    except BusCommandError as exc:
        raise click.BadParameter(str(exc), ctx, param) from None
    return value


def bus_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--port, --baud and --json, shared by every bus command."""

    @click.option(
        "--port", "-p", required=True, envvar="SNAKEBOT_BUS_PORT", show_envvar=True, help=PORT_HELP
    )
    @click.option(
        "--baud",
        "-b",
        type=click.IntRange(min=1),
        default=DEFAULT_BAUDRATE,
        show_default=True,
        callback=_servo_baud,
        help="Bit rate of the bus (AX-12 factory setting: 1000000).",
    )
    @click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        return func(*args, **kwargs)

    return wrapper


@contextlib.contextmanager
def _on_the_bus(port: str, baud: int) -> Iterator[DxlClient]:
    """The bus at ``port``. A :class:`BusCommandError` raised while it is open is the
    servos' failure (no reply, a write not taken), not bad input: ``error: ...`` and exit
    status 1. Checks of the command line itself come before this, so they keep status 2."""
    with DxlClient(port, baud) as client:
        try:
            yield client
        except BusCommandError as exc:
            _device_failure(str(exc))


def _device_failure(message: str) -> NoReturn:
    """``error: message`` and exit status 1: the servos failed, the command line was fine."""
    click.echo(f"error: {' '.join(message.split())}", err=True)
    raise click.exceptions.Exit(EXIT_RUNTIME)


def _emit(as_json: bool, data: object, text: str) -> None:
    click.echo(dumps(data) if as_json else text)


def _servo_line(info: ServoInfo) -> str:
    firmware = "?" if info.firmware is None else str(info.firmware)
    number = "" if info.model_number is None else f" (model {info.model_number})"
    model = info.model or ("unknown" if info.model_number is not None else "PING only")
    status = "ok" if not info.error else info.error.describe()
    return f"{info.id:>4}  {model + number:<22} {firmware:>8}  {info.baud:>8}  {status}"


HEADER = f"{'ID':>4}  {'model':<22} {'firmware':>8}  {'baud':>8}  status"


@click.group("bus")
def bus() -> None:
    """Servo chores on a Dynamixel bus: find servos, read and write their registers by
    name, change an ID or a baud rate.

    Connect the servos through a bus adapter (USB2Dynamixel or similar, Protocol 1.0) and
    power them (USB does not). Every command takes --port, --baud (default 1000000, the
    AX-12 factory rate) and --json. Start with

    \b
        snakebot bus scan --port /dev/ttyUSB0

    Register names come from the AX-12 control table (snakebot.facts.devices): write them as
    you like, e.g. goal-position, "Goal Position" or goal_position, or give the address.
    """


@bus.command("scan")
@bus_options
@click.option(
    "--ids", default="0-253", show_default=True, help="IDs to try, e.g. 0-253 or 1,2,5-7."
)
@click.option(
    "--bauds",
    help="Rates to try instead of --baud, comma-separated; 'common' for the AX-12's "
    "usual ones (1000000 ... 9615), 'all' for every rate an AX or MX servo is "
    "tabulated at (up to 3000000).",
)
@click.pass_context
def scan_command(
    ctx: click.Context, port: str, baud: int, as_json: bool, ids: str, bauds: str | None
) -> None:
    """Find the servos on the bus: PING every ID, and report each one's model and
    firmware version as it is found.

    An ID whose reply arrives damaged (noise, a corrupted echo on a one-wire adapter)
    is tried again; one that never answers cleanly is listed as garbled rather than
    stopping the scan. Ctrl-C stops early and still lists what was found (exit 130).
    Exit status 1 when no servo answers.

    A silent ID costs the PING, the longest Return Delay Time a servo may have and the
    first byte of a reply on the wire, plus the USB adapter's latency and the host's
    margin (SNAKEBOT_LATENCY_MS, SNAKEBOT_MARGIN_MS): at 1000000 baud all 254 IDs take
    about 1 s with an adapter whose latency timer is lowered to 1 ms, about 5 s at an
    FTDI adapter's default 16 ms. A reply that comes after its ID's wait still counts
    for the ID it names. A servo whose baud rate you do not know turns up with --bauds
    common, or --bauds all (each further rate begins after a pause of 100 ms, the time
    a servo takes to drop a packet begun by the last rate's bytes).
    """
    id_list = register_values.parse_ids(ids)
    rates = register_values.parse_bauds(bauds) if bauds else [baud]
    found: list[ServoInfo] = []
    garbled: list[Probe] = []
    interrupted = False
    if not as_json:
        span = f"IDs {ids}" if len(id_list) > 1 else f"ID {id_list[0]}"
        at = f"{rates[0]} baud" if len(rates) == 1 else f"{len(rates)} baud rates"
        click.echo(f"Scanning {span} at {at} on {port} ...")
    bar = click.progressbar(
        length=len(id_list) * len(rates), label="Scanning", file=sys.stderr, show_pos=True
    )
    with open_port(port, rates[0], timeout=0) as link, bar:
        try:
            for result in bus_scan.scan_probes(link, id_list, rates):
                bar.update(1)
                if result.info is not None:
                    if not found and not as_json:
                        click.echo(HEADER)
                    found.append(result.info)
                    if not as_json:
                        click.echo(_servo_line(result.info))
                elif result.garbled:
                    garbled.append(result)
        except KeyboardInterrupt:
            interrupted = True
    if as_json:
        click.echo(
            dumps(
                {
                    "port": port,
                    "ids": id_list,
                    "bauds": rates,
                    "found": [s.as_dict() for s in found],
                    "garbled": [g.as_dict() for g in garbled],
                    "interrupted": interrupted,
                }
            )
        )
    else:
        for g in garbled:
            click.echo(
                f"ID {g.id} at {g.baud} baud: only damaged replies "
                f"({1 + bus_scan.SCAN_RETRIES} tries); check the cabling, or two servos "
                "sharing this ID"
            )
        if found:
            click.echo(f"Found {len(found)} servo{'s' if len(found) != 1 else ''}.")
    if interrupted:
        click.echo("Scan stopped by Ctrl-C: the list above is what was found so far.", err=True)
        ctx.exit(EXIT_INTERRUPTED)
    if not found:
        click.echo(
            "error: no servo answered. Check that the servos are powered (USB does not "
            "power them) and cabled, and try other rates with --bauds common or --bauds all.",
            err=True,
        )
        ctx.exit(1)


@bus.command("ping")
@bus_options
@click.argument("ids", nargs=-1, required=True, type=click.IntRange(0, register_values.MAX_ID))
def ping_command(port: str, baud: int, as_json: bool, ids: tuple[int, ...]) -> None:
    """PING servo IDS (one or more) and report model, firmware and error bits.

    Fails (exit status 1) if any of them does not answer.
    """
    with _on_the_bus(port, baud) as client:
        results = {servo_id: bus_scan.identify(client, servo_id) for servo_id in ids}
    found = [info for info in results.values() if info is not None]
    missing = [servo_id for servo_id, info in results.items() if info is None]
    if as_json:
        click.echo(
            dumps(
                {
                    "port": port,
                    "baud": baud,
                    "found": [s.as_dict() for s in found],
                    "missing": missing,
                }
            )
        )
    elif found:
        click.echo(HEADER)
        for info in found:
            click.echo(_servo_line(info))
    if missing:
        who = ", ".join(map(str, missing))
        _device_failure(
            f"no reply from servo{'s' if len(missing) > 1 else ''} {who} at {baud} baud: "
            "check that the servos are powered (USB does not power them) and cabled, the "
            "baud rate (snakebot bus scan --bauds common finds it) and the ID (snakebot bus "
            "scan lists them)"
        )


@bus.command("read")
@bus_options
@click.argument("servo_id", metavar="ID", type=click.IntRange(0, register_values.MAX_ID))
@click.argument("registers", nargs=-1)
def read_command(
    port: str, baud: int, as_json: bool, servo_id: int, registers: tuple[str, ...]
) -> None:
    """Read REGISTERS of servo ID (all of them if none are named) and decode them.

    \b
        snakebot bus read 1 present-position present-voltage --port /dev/ttyUSB0
        snakebot bus read 1 36 --port /dev/ttyUSB0        # the same register by address
    """
    entries = [register_values.resolve_register(r) for r in registers]
    with _on_the_bus(port, baud) as client:
        table, values = bus_registers.read_registers(client, servo_id, entries)
    if as_json:
        click.echo(dumps({"id": servo_id, "model": table.model, "registers": values}))
        return
    click.echo(f"servo {servo_id} ({table.model}):")
    for v in values:
        rw = "" if v["access"] == "RW" else "  (read-only)"
        click.echo(f"  {v['address']:>3}  {v['name']:<22} {register_values.describe_value(v)}{rw}")


@bus.command("write")
@bus_options
@click.argument("servo_id", metavar="ID", type=click.IntRange(0, register_values.MAX_ID))
@click.argument("register")
@click.argument("value")
def write_command(
    port: str, baud: int, as_json: bool, servo_id: int, register: str, value: str
) -> None:
    """Write VALUE to REGISTER of servo ID: a raw value (decimal or 0x hex) or an
    amount with a unit the register's scale converts (30deg, 0.5rad, 50rpm, 11.5V).

    Read-only registers and values outside the register's range are refused before
    anything is sent. Change an ID with `snakebot bus set-id` and a baud rate with
    `snakebot bus set-baud`, which check the result.

    \b
        snakebot bus write 1 goal-position 512 --port /dev/ttyUSB0
        snakebot bus write 1 goal-position 150deg --port /dev/ttyUSB0
        snakebot bus write 1 moving-speed 50rpm --port /dev/ttyUSB0
        snakebot bus write 1 led 1 --port /dev/ttyUSB0
    """
    entry = register_values.resolve_register(register)
    number = register_values.parse_value(entry, value)
    redirect = {"ID": "set-id", "Baud Rate": "set-baud"}.get(entry.name)
    if redirect:
        raise BusCommandError(
            f"change {entry.name} with `snakebot bus {redirect}`, which checks the result "
            "(and, for an ID, that no other servo has it)"
        )
    register_values.check_write(entry, number)
    with _on_the_bus(port, baud) as client:
        back = bus_registers.write_register(client, servo_id, entry, number)
    decoded = register_values.decode(entry, number)
    if as_json:
        click.echo(
            dumps(
                {
                    "id": servo_id,
                    "register": entry.name,
                    "address": entry.address,
                    "value": number,
                    "read_back": back,
                }
            )
        )
        return
    shown = register_values.describe_value(decoded)
    text = f"servo {servo_id}: {entry.name} ({entry.address}) = {shown}"
    if back is not None:
        text += ", reads back " + ("the same" if back == number else str(back))
    click.echo(text)
    if entry.name == "Lock" and number:
        click.echo("The EEPROM area is now locked until the servo loses power.")


@bus.command("set-id")
@bus_options
@click.argument("old_id", metavar="ID", type=click.IntRange(0, register_values.MAX_ID))
@click.argument("new_id", metavar="NEW_ID", type=click.IntRange(0, register_values.MAX_ID))
def set_id_command(port: str, baud: int, as_json: bool, old_id: int, new_id: int) -> None:
    """Give servo ID the ID NEW_ID (stored in its EEPROM).

    Refuses if another device already answers to NEW_ID. Servos leave the factory as
    ID 1, so connect new servos one at a time and renumber each:

    \b
        snakebot bus set-id 1 10 --port /dev/ttyUSB0
    """
    if old_id == new_id:
        raise BusCommandError(
            f"ID and NEW_ID are both {old_id}: give NEW_ID the ID the servo should take"
        )
    with _on_the_bus(port, baud) as client:
        info = bus_ids.set_id(client, old_id, new_id)
    _emit(
        as_json,
        {"old_id": old_id, "new_id": new_id, "servo": info.as_dict()},
        f"servo {old_id} is now ID {new_id} ({info.label}), and answers there.",
    )


@bus.command("set-baud")
@bus_options
@click.argument("servo_id", metavar="ID", type=click.IntRange(0, register_values.MAX_ID))
@click.argument("rate", required=False, type=NumberType(1))
@click.option(
    "--value",
    "register",
    type=click.IntRange(0, 254),
    help="Give the Baud Rate register value n instead of RATE.",
)
def set_baud_command(
    port: str, baud: int, as_json: bool, servo_id: int, rate: float | None, register: int | None
) -> None:
    """Set the baud rate of servo ID to RATE bit/s (stored in its EEPROM).

    An AX-12 runs at 2,000,000 / (n + 1) bit/s, n being its Baud Rate register (0-254):
    n=1 is 1000000 (factory), 3 is 500000, 16 is 117647, 34 is 57142, 207 is 9615. RATE
    must come within 3 % of one of these. After the change the servo only hears that
    rate: this command reopens the port at RATE to check, and from then on every
    command needs --baud RATE for it.

    \b
        snakebot bus set-baud 1 500000 --port /dev/ttyUSB0
        snakebot bus ping 1 --baud 500000 --port /dev/ttyUSB0
    """
    if (rate is None) == (register is None):
        raise BusCommandError("give either RATE (bit/s) or --value N, e.g. set-baud 1 500000")
    if register is None:
        assert rate is not None
        register = register_values.baud_register(rate)
        host_baud = round(rate)
    else:
        host_baud = round(register_values.baud_from_register(register))
    with _on_the_bus(port, baud) as client:
        change = bus_ids.set_baud(client, servo_id, register, host_baud)
    _emit(
        as_json,
        {
            "id": servo_id,
            "register": change.register,
            "servo_baud": change.servo_baud,
            "host_baud": change.host_baud,
            "verified": change.verified,
        },
        f"servo {servo_id} now runs at {change.servo_baud:.0f} bit/s (Baud Rate register "
        f"{change.register}: 2,000,000 / ({change.register} + 1)) and answers at "
        f"{change.host_baud} baud. Reopen the port at the new rate to reach it: "
        f"add --baud {change.host_baud} to later commands.",
    )
