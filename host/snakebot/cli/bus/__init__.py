"""`snakebot bus`: servo chores on a Dynamixel bus through a direct adapter (USB2Dynamixel,
U2D2 in Protocol 1.0, or the emulator): scan, ping, read, write, set-id, set-baud
(here), and ``bus play`` (``play``). The work itself is in :mod:`snakebot.link.bus`.

May import: as the ``cli`` layer (every layer below it)."""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Iterator
from typing import Any, NoReturn

import click

from snakebot.cli.errors import EXIT_RUNTIME
from snakebot.cli.options import BusLink, bauds_option, bus_options, ids_option
from snakebot.cli.output import dumps, echo_json
from snakebot.cli.params import NumberType
from snakebot.cli.signals import interrupted_status
from snakebot.cli.troubleshooting import error_line
from snakebot.formats import register_values
from snakebot.formats.register_values import BusCommandError
from snakebot.link.bus import ids as bus_ids
from snakebot.link.bus import registers as bus_registers
from snakebot.link.bus import scan as bus_scan
from snakebot.link.bus.scan import Probe, ServoInfo
from snakebot.link.transport import DxlClient, adapter, open_port

"""What a shell reports for a command stopped by Ctrl-C (128 + SIGINT)."""


@contextlib.contextmanager
def _on_the_bus(bus: BusLink) -> Iterator[DxlClient]:
    """The bus on the command line. A :class:`BusCommandError` raised while it is open is the
    servos' failure (no reply, a write not taken), not bad input: ``error: ...`` and exit
    status 1. Checks of the command line itself come before this, so they keep status 2."""
    with bus.open() as client:
        try:
            yield client
        except BusCommandError as exc:
            _device_failure(str(exc))


def _device_failure(message: str) -> NoReturn:
    """``error: message`` and exit status 1: the servos failed, the command line was fine."""
    click.echo(error_line(" ".join(message.split())), err=True)
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
@ids_option
@bauds_option(instead=" instead of --baud")
@click.option(
    "--latency-timer",
    type=click.IntRange(1, 255),
    help="First set the USB adapter's latency timer to this many ms (FTDI on Linux; 1 is "
    "what the Dynamixel tools advise). Writing it needs root or a udev rule.",
)
@click.pass_context
def scan_command(
    ctx: click.Context,
    bus: BusLink,
    as_json: bool,
    ids: str,
    bauds: str | None,
    latency_timer: int | None,
) -> None:
    """Find the servos on the bus: PING every ID, and report each one's model and
    firmware version as it is found.

    \b
        snakebot bus scan --port /dev/ttyUSB0
        snakebot bus scan --port /dev/ttyUSB0 --ids 1-30 --bauds common

    An ID whose reply arrives damaged (noise, a corrupted echo on a one-wire adapter)
    is tried again; one that never answers cleanly is listed as garbled rather than
    stopping the scan. Ctrl-C stops early and still lists what was found (exit 130).
    Exit status 1 when no servo answers.

    A silent ID costs the PING, the longest Return Delay Time a servo may have and the
    first byte of a reply on the wire, plus the USB adapter's latency (its latency timer
    as Linux shows it for an FTDI adapter, none for the emulator or a pseudo-terminal;
    else SNAKEBOT_LATENCY_MS) and a small host margin (SNAKEBOT_MARGIN_MS). A reply that
    comes after its ID's wait still counts for the ID it names, and every silent ID is
    PINGed once more at the end. At 1000000 baud all 254 IDs take about 0.5 s on the
    emulator, 1 s with an adapter whose latency timer is lowered to 1 ms
    (--latency-timer 1), 9 s at an FTDI adapter's default 16 ms. A servo whose baud
    rate you do not know turns up with --bauds common, or --bauds all (each further
    rate begins after a pause of 100 ms, the time a servo takes to drop a packet begun
    by the last rate's bytes).
    """
    id_list = register_values.parse_ids(ids)
    port = bus.port
    rates = register_values.parse_bauds(bauds) if bauds else [bus.baud]
    report = bus_scan.ScanReport(port, id_list, rates)
    interrupted = 0  # the exit status of the signal that stopped the scan
    if not as_json:
        span = f"IDs {ids}" if len(id_list) > 1 else f"ID {id_list[0]}"
        at = f"{rates[0]} baud" if len(rates) == 1 else f"{len(rates)} baud rates"
        click.echo(f"Scanning {span} at {at} on {port} ...")
    bar = click.progressbar(
        length=len(id_list) * len(rates), label="Scanning", file=sys.stderr, show_pos=True
    )

    def seen(probe: Probe) -> None:
        bar.update(1)
        if probe.info is not None and not as_json:
            if len(report.found) == 1:
                click.echo(HEADER)
            click.echo(_servo_line(probe.info))

    _adapter_latency(port, latency_timer, quiet=as_json)
    with open_port(port, rates[0], timeout=0) as link, bar:
        try:
            bus_scan.scan_into(report, link, seen)
        except KeyboardInterrupt as exc:
            interrupted = interrupted_status(exc)
    if as_json:
        click.echo(dumps(report.as_dict()))
    else:
        for g in report.garbled:
            click.echo(
                f"ID {g.id} at {g.baud} baud: only damaged replies "
                f"({1 + bus_scan.SCAN_RETRIES} tries); check the cabling, or two servos "
                "sharing this ID"
            )
        if report.found:
            n = len(report.found)
            click.echo(f"Found {n} servo{'s' if n != 1 else ''}.")
    if interrupted:
        click.echo("Scan stopped by Ctrl-C: the list above is what was found so far.", err=True)
        ctx.exit(interrupted)
    if not report.found:
        click.echo(
            error_line(
                "no servo answered. Check that the servos are powered (USB does not "
                "power them) and cabled, and try other rates with --bauds common or --bauds all."
            ),
            err=True,
        )
        ctx.exit(1)


def _adapter_latency(port: str, latency_timer: int | None, *, quiet: bool) -> None:
    """Set the adapter's latency timer when asked; else advise lowering a slow one."""
    if latency_timer is not None:
        adapter.set_latency_timer(port, latency_timer)
        return
    timer = adapter.latency_timer_ms(port)
    if timer is not None and timer > adapter.LOWERED_LATENCY_MS and not quiet:
        click.echo(
            f"note: the adapter's latency timer is {timer} ms, and every silent ID waits "
            f"that long; {adapter.lowering_fix(port)}",
            err=True,
        )


@bus.command("ping")
@bus_options
@click.argument("ids", nargs=-1, required=True, type=click.IntRange(0, register_values.MAX_ID))
def ping_command(bus: BusLink, as_json: bool, ids: tuple[int, ...]) -> None:
    """PING servo IDS (one or more) and report model, firmware and error bits.

    Fails (exit status 1) if any of them does not answer.

    \b
        snakebot bus ping 1 --port /dev/ttyUSB0
        snakebot bus ping 10 11 15 16 --port /dev/ttyUSB0
    """
    with _on_the_bus(bus) as client:
        results = {servo_id: bus_scan.identify(client, servo_id) for servo_id in ids}
    found = [info for info in results.values() if info is not None]
    missing = [servo_id for servo_id, info in results.items() if info is None]
    if as_json:
        click.echo(
            dumps(
                {
                    "port": bus.port,
                    "baud": bus.baud,
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
            f"no reply from servo{'s' if len(missing) > 1 else ''} {who} at {bus.baud} baud: "
            "check that the servos are powered (USB does not power them) and cabled, the "
            "baud rate (snakebot bus scan --bauds common finds it) and the ID (snakebot bus "
            "scan lists them)"
        )


ROBOT_HELP = (
    "A robot file (or snake5, ...): positions of the servo's joint are joint angles (its zero "
    "tick, sign and limits applied; a goal outside the limits is refused)."
)


def _joint_of(robot: str | None, servo_id: int) -> Any:
    """The joint that servo ``servo_id`` drives in ``robot`` (None without --robot)."""
    if robot is None:
        return None
    from snakebot.model.robots import load_robot

    loaded = load_robot(robot)
    for joint in loaded.joints:
        if joint.servo_id == servo_id:
            return joint
    raise BusCommandError(
        f"servo {servo_id} drives no joint of {loaded.name} (its servos: "
        f"{', '.join(map(str, loaded.servo_ids))}): give one of those IDs, or drop --robot"
    )


def _joint_goal(joint: Any, text: str) -> int | None:
    """The tick for the joint angle ``text`` (30deg, -0.2rad); None if ``text`` is not an
    angle (raw ticks, absdeg: those stay as written)."""
    amount = register_values.split_amount(text)
    if amount is None or amount[1] not in register_values.ANGLE_UNITS:
        return None
    value, unit = amount
    phi = math.radians(value) if unit == "deg" else value
    if not joint.min_rad - 1e-9 <= phi <= joint.max_rad + 1e-9:
        raise BusCommandError(
            f"{text} is outside joint {joint.name}'s limits ({math.degrees(joint.min_rad):g} "
            f"to {math.degrees(joint.max_rad):g} deg): give an angle inside them"
        )
    return int(joint.angle_to_tick(phi))


@bus.command("read")
@bus_options
@click.argument("servo_id", metavar="ID", type=click.IntRange(0, register_values.MAX_ID))
@click.argument("registers", nargs=-1)
@click.option("--robot", metavar="FILE", help=ROBOT_HELP)
def read_command(
    bus: BusLink, as_json: bool, servo_id: int, registers: tuple[str, ...], robot: str | None
) -> None:
    """Read REGISTERS of servo ID (all of them if none are named) and decode them.

    \b
        snakebot bus read 1 present-position present-voltage --port /dev/ttyUSB0
        snakebot bus read 1 36 --port /dev/ttyUSB0        # the same register by address
        snakebot bus read 10 present-position --robot snake5 --port /dev/ttyUSB0

    A position reads as its angle from the centre and on the 0-300 dial; with --robot,
    also as the joint's angle.
    """
    entries = [register_values.resolve_register(r) for r in registers]
    joint = _joint_of(robot, servo_id)
    with _on_the_bus(bus) as client:
        table, values = bus_registers.read_registers(client, servo_id, entries)
    if joint is not None:
        for v in values:
            if "from_centre_deg" in v:
                v["joint"] = joint.name
                v["joint_deg"] = round(math.degrees(joint.tick_to_angle(int(v["value"]))), 1)
    if echo_json(as_json, {"id": servo_id, "model": table.model, "registers": values}):
        return
    click.echo(f"servo {servo_id} ({table.model}):")
    for v in values:
        rw = "" if v["access"] == "RW" else "  (read-only)"
        joint_text = f"; joint {v['joint']} {v['joint_deg']:+g} deg" if "joint" in v else ""
        click.echo(
            f"  {v['address']:>3}  {v['name']:<22} {register_values.describe_value(v)}"
            f"{joint_text}{rw}"
        )


@bus.command("write", context_settings={"ignore_unknown_options": True})  # -30deg
@bus_options
@click.argument("servo_id", metavar="ID", type=click.IntRange(0, register_values.MAX_ID))
@click.argument("register")
@click.argument("value")
@click.option("--robot", metavar="FILE", help=ROBOT_HELP)
def write_command(
    bus: BusLink,
    as_json: bool,
    servo_id: int,
    register: str,
    value: str,
    robot: str | None,
) -> None:
    """Write VALUE to REGISTER of servo ID: a raw value (decimal or 0x hex) or an
    amount with a unit the register's scale converts (30deg, 0.5rad, 50rpm, 11.5V).

    \b
    Positions (goal-position, present-position, the angle limits) as angles:
    30deg is 30 degrees from the servo's centre (tick 512), counter-clockwise
    seen from the horn; -30deg as far the other way; 0.5rad the same in radians.
    The servo's own 0-300 degree dial, as ROBOTIS's Dynamixel Wizard shows it
    (150 is the centre), is written 150absdeg; a whole number is raw ticks
    (0-1023). With --robot FILE an angle is the joint's angle: from the joint's
    zero tick, in its sign, and refused outside its limits.

    Read-only registers and values outside the register's range are refused before
    anything is sent. Change an ID with `snakebot bus set-id` and a baud rate with
    `snakebot bus set-baud`, which check the result.

    \b
        snakebot bus write 1 goal-position 512 --port /dev/ttyUSB0
        snakebot bus write 1 goal-position 30deg --port /dev/ttyUSB0      # tick 614
        snakebot bus write 1 goal-position 180absdeg --port /dev/ttyUSB0  # the same
        snakebot bus write 10 goal-position 30deg --robot snake5 --port /dev/ttyUSB0
        snakebot bus write 1 moving-speed 50rpm --port /dev/ttyUSB0
        snakebot bus write 1 led 1 --port /dev/ttyUSB0
    """
    entry = register_values.resolve_register(register)
    joint = _joint_of(robot, servo_id)  # read and checked even where no position needs it
    if not register_values.is_position(entry):
        joint = None
    given = _joint_goal(joint, value) if joint is not None else None
    entry, number = register_values.parse_write(register, value, given)
    with _on_the_bus(bus) as client:
        back = bus_registers.write_register(client, servo_id, entry, number)
    decoded = register_values.decode(entry, number)
    said = {}  # with --robot, the joint's angle the value stands for, as `bus read` says it
    if joint is not None:
        said = {
            "joint": joint.name,
            "joint_deg": round(math.degrees(joint.tick_to_angle(number)), 1),
        }
    if as_json:
        click.echo(
            dumps(
                {
                    "id": servo_id,
                    "register": entry.name,
                    "address": entry.address,
                    "value": number,
                    **said,
                    "read_back": back,
                }
            )
        )
        return
    shown = register_values.describe_value(decoded)
    if said:
        shown += f"; joint {said['joint']} {said['joint_deg']:+g} deg"
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
def set_id_command(bus: BusLink, as_json: bool, old_id: int, new_id: int) -> None:
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
    with _on_the_bus(bus) as client:
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
    bus: BusLink, as_json: bool, servo_id: int, rate: float | None, register: int | None
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
    register, host_baud = register_values.baud_setting(rate, register)
    with _on_the_bus(bus) as client:
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
