"""The options more than one command takes, each declared once: its name, its help, its
default and its check.

A command stacks these decorators instead of spelling the option again, as python-can's
``can/cli.py`` does for its bus arguments. The port options hand the command one value
(:class:`BusLink` or :class:`ControllerLink`) instead of the port, the rate and the ID
one by one, so no signature restates them.

* Ports: :func:`bus_options` (a servo bus through an adapter), :func:`controller_options`
  (the controller's PC link), :func:`port_option` (any other port), :func:`controller_id_option`.
* Robots: :func:`robot_argument` (ROBOT), :func:`robot_option` (--robot, -r).
* Worlds and the emulator: :func:`world_option`, :func:`ideal_option`, :func:`mu_option`,
  :func:`board_option`, :func:`firmware_option`, :func:`link_option`.
* Waves: :func:`wave_options` (-A, -w, -d), :func:`offset_option`, :func:`speed_option`,
  :func:`steer_option`, :func:`rate_option`, :func:`form_option`.
* Plans: :func:`target_options` (--to, --from, --tolerance, --heading-tolerance).
* Servo scans: :func:`ids_option`, :func:`bauds_option`.
* Output: :func:`json_option`, :func:`output_option`, :func:`plot_option`,
  :func:`video_option`, :func:`foxglove_option` (the robot live in Foxglove).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

from snakebot.cli.params import (
    ANGLE,
    ANGLES,
    INPUT_PATH,
    NUMBER,
    OUTPUT_PATH,
    PLOT_PATH,
    POSE,
    ROBOT,
    NumberType,
    OutputPathType,
    controller_port,
)
from snakebot.facts.boards import PC_LINK_BAUD

if TYPE_CHECKING:
    from snakebot.link.controller.client import ControllerClient
    from snakebot.link.transport import DxlClient

F = TypeVar("F", bound=Callable[..., Any])
Decorator = Callable[[F], F]

VIDEO_WORDS = (
    "in 3-D from MuJoCo's renderer (offscreen; the top view in 2-D where it cannot start), "
    "the camera following the body, its path on a 1 m grid, the time and the joint angles "
    "overlaid: .mp4 or .gif"
)


class SizeType(click.ParamType):
    name = "WxH"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, tuple):
            return value
        from snakebot.plots.video import VideoError, parse_size

        try:
            return parse_size(str(value))
        except VideoError as exc:
            self.fail(str(exc), param, ctx)


def stack(*decorators: Callable[[Any], Any]) -> Callable[[F], F]:
    """The decorators as one, applied as if written one above the other in this order
    (so the options appear in ``--help`` in this order)."""

    def apply(func: F) -> F:
        for decorator in reversed(decorators):
            func = decorator(func)
        return func

    return apply


# --- ports ---------------------------------------------------------------------------------

BUS_PORT_ENV = "SNAKEBOT_BUS_PORT"
CONTROLLER_PORT_ENV = "SNAKEBOT_PORT"
CONTROLLER_ID_ENV = "SNAKEBOT_CONTROLLER_ID"


@dataclass(frozen=True)
class PortKind:
    """What is at the other end of a --port: its help, the environment variable that
    may name it, and the command that emulates it where a sim:// URL cannot (a sim://
    URL emulates servos only)."""

    help: str
    envvar: str | None = None
    server: str | None = None


BUS_PORT = PortKind(
    "The bus adapter: a device (/dev/ttyUSB0, COM3), a pyserial URL, or sim://?ids=1,2 for "
    "the emulator.",
    envvar=BUS_PORT_ENV,
)
CONTROLLER_PORT = PortKind(
    "The controller's PC link: the CM-530's USB-serial device (/dev/ttyUSB0, COM3), a "
    "pyserial URL, or the pseudo-terminal of the emulated controller (`snakebot sim "
    "serve` prints it; sim:// URLs emulate servos only).",
    envvar=CONTROLLER_PORT_ENV,
    server="snakebot sim serve",
)
BOOTLOADER_PORT = PortKind(
    "The CM-530's PC link: its USB-serial device (/dev/ttyUSB0, COM3), a pyserial URL, "
    "or the pseudo-terminal of `snakebot sim bootloader`.",
    envvar=CONTROLLER_PORT_ENV,
    server="snakebot sim bootloader",
)
ANY_PORT = PortKind(
    "The port to examine: the CM-530's PC link, a USB2Dynamixel's servo bus, a pyserial "
    "URL (sim://...) or an emulator's pseudo-terminal."
)


def port_option(kind: PortKind, *, purpose: str | None = None, required: bool = True) -> Decorator:
    """--port, -p for a port of ``kind``. ``purpose`` says what the command does with
    it, where that is not the command's job. Only a port the command needs is read from
    the environment: an optional one set there would change what the command does."""
    return click.option(
        "--port",
        "-p",
        required=required,
        envvar=kind.envvar if required else None,
        show_envvar=required and kind.envvar is not None,
        callback=controller_port(kind.server) if kind.server else None,
        help=f"{purpose}. {kind.help}" if purpose else kind.help,
    )


def _servo_baud(ctx: click.Context, param: click.Parameter, value: int) -> int:
    """--baud on a servo bus: a rate some described servo runs at."""
    from snakebot.formats import register_values  # the device tables: when a command runs

    try:
        register_values.check_bus_baud(value)
    except register_values.BusCommandError as exc:
        raise click.BadParameter(str(exc), ctx, param) from None
    return value


def _link_baud(ctx: click.Context, param: click.Parameter, value: int) -> int:
    """--baud on the PC link: within the rates Dynamixel devices are tabulated at: below
    the slowest a reply's timeout (it scales with the byte time) runs to minutes, above
    the fastest no serial port goes (and the operating system refuses the number)."""
    from snakebot.formats import register_values

    slowest, fastest = register_values.slowest_bps(), register_values.fastest_bps()
    if not slowest <= value <= fastest:
        side = f"slower than any Dynamixel device runs (the slowest: {slowest})"
        if value > fastest:
            side = f"faster than any Dynamixel device runs (the fastest: {fastest})"
        raise click.BadParameter(
            f"{value} bit/s is {side}; the firmware's PC link runs at {PC_LINK_BAUD}",
            ctx,
            param,
        )
    return value


def _baud_option(default: int, check: Callable[..., int], help: str) -> Decorator:
    return click.option(
        "--baud",
        "-b",
        type=click.IntRange(min=1),
        default=default,
        show_default=True,
        callback=check,
        help=help,
    )


def _default_controller_id() -> int:
    from snakebot.facts.controller import load  # the controller's table: when first asked

    return load().default_id


def controller_id_option(func: F) -> F:
    """--id, for every command that talks to the controller (its default from the
    controller's table, read when a command that has it loads)."""
    return click.option(
        "--id",
        "controller_id",
        type=click.IntRange(0, 253),
        default=_default_controller_id(),
        show_default=True,
        envvar=CONTROLLER_ID_ENV,
        help="The controller's Protocol 1.0 ID on the PC link.",
    )(func)


@dataclass(frozen=True)
class BusLink:
    """A servo bus as the command line names it: --port at --baud."""

    port: str
    baud: int

    def open(self) -> DxlClient:
        from snakebot.link.transport import DxlClient

        return DxlClient(self.port, self.baud)


@dataclass(frozen=True)
class ControllerLink:
    """The controller as the command line names it: --port at --baud, ID --id."""

    port: str
    baud: int = PC_LINK_BAUD
    controller_id: int = field(default_factory=_default_controller_id)

    def open(self) -> ControllerClient:
        """The controller client (PortError, exit 2, if the port cannot be opened)."""
        from snakebot.link.controller.client import ControllerClient

        return ControllerClient.open(self.port, self.baud, self.controller_id)


def _bundled(func: Callable[..., Any], name: str, make: Callable[..., Any], *keys: str) -> Any:
    """``func`` taking ``name=make(**those keys)`` in place of the keys one by one."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        kwargs[name] = make(**{key: kwargs.pop(key) for key in keys})
        return func(*args, **kwargs)

    return wrapper


def bus_options(func: F) -> F:
    """--port, --baud and --json of every command on a servo bus; the command takes
    ``bus`` (a :class:`BusLink`) and ``as_json``."""
    from snakebot.link.transport import DEFAULT_BAUDRATE  # only where a command has it

    return stack(
        port_option(BUS_PORT),
        _baud_option(
            DEFAULT_BAUDRATE, _servo_baud, "Bit rate of the bus (AX-12 factory setting: 1000000)."
        ),
        json_option(),
    )(_bundled(func, "bus", BusLink, "port", "baud"))


def controller_options(func: F) -> F:
    """--port, --baud, --id and --json of every command that talks to the controller;
    the command takes ``link`` (a :class:`ControllerLink`) and ``as_json``."""
    return stack(
        port_option(CONTROLLER_PORT),
        _baud_option(
            PC_LINK_BAUD, _link_baud, f"Bit rate of the PC link (the firmware's: {PC_LINK_BAUD})."
        ),
        controller_id_option,
        json_option(),
    )(_bundled(func, "link", ControllerLink, "port", "baud", "controller_id"))


# --- robots --------------------------------------------------------------------------------


robot_argument: Decorator = click.argument("robot", metavar="ROBOT")
"""ROBOT: a built-in robot's name or a robot file (the command's help says which kinds)."""


def robots_named() -> str:
    """What names a robot, wherever one is asked for."""
    from snakebot.model.robots import BUILTIN_ROBOTS  # the robot loader: when first asked

    return f"{', '.join(BUILTIN_ROBOTS)} or a robot .toml file"


def robot_option(
    purpose: str, *, default: str | None = None, otherwise: str | None = None
) -> Decorator:
    """--robot, -r: ``purpose`` (what the robot is for), then what names one; without a
    ``default``, ``otherwise`` says what the command does without it. The robot is
    checked while parsing (:data:`ROBOT`): a bad one is exit 2 even where this run has
    no use for it."""
    tail = f" (default: {otherwise})" if otherwise else ""
    return click.option(
        "--robot",
        "-r",
        type=ROBOT,
        default=default,
        show_default=default is not None,
        help=f"{purpose}: {robots_named()}{tail}.",
    )


def roster_option(func: F) -> F:
    """--robot of the commands that start a wave on the controller."""
    return robot_option(
        "Set the controller's roster (servo IDs, directions, zero ticks, limits) from this "
        "robot first"
    )(func)


# --- worlds and the emulator ---------------------------------------------------------------

WORLD_HELP = (
    "What moves the body: kinematic, the minimum-slip wheel model, from the servos' "
    "positions; mujoco, MuJoCo's physics, from the robot TOML's [physics] table (the body "
    "has mass, its wheels can slip and the servos run out of torque; where this build has "
    "MuJoCo)."
)


def world_option(default: str | None = None, *, note: str | None = None) -> Decorator:
    """--world: kinematic or mujoco (the default: the emulator's unless the command's own
    job says otherwise)."""
    # the worlds' module loads the emulator: only where a command has the option
    from snakebot.sim.physics.select import DEFAULT_WORLD, WORLDS

    return click.option(
        "--world",
        type=click.Choice(WORLDS),
        default=DEFAULT_WORLD if default is None else default,
        show_default=True,
        help=f"{WORLD_HELP} {note}" if note else WORLD_HELP,
    )


ideal_option: Decorator = click.option(
    "--ideal",
    is_flag=True,
    help="Ideal servos that reach every goal at once (default: modelled AX-12s that lag).",
)

mu_option: Decorator = click.option(
    "--mu",
    type=NumberType(0, low_open=True),
    help="With the mujoco world: the wheel-floor friction coefficient (default: the robot's).",
)


def board_option(f: F) -> F:
    """``--board``: which emulated board runs the firmware (``board``), the CM-530 by default."""
    from snakebot.sim.serve import BOARDS, DEFAULT_BOARD

    return click.option(
        "--board",
        type=click.Choice(BOARDS),
        default=DEFAULT_BOARD,
        show_default=True,
        help="cm530: the CM-530's own image on the emulated STM32F103RE (in this process); "
        "qemu: the qemu board's build of the same firmware under qemu-system-arm.",
    )(f)


firmware_option: Decorator = click.option(
    "--firmware",
    type=INPUT_PATH,
    default=None,
    help="Firmware to run. cm530: the CM-530 image (.bin, .hex or .elf). qemu: the qemu "
    "board's application ELF (the boot stub beside it goes in front) or a whole-flash .bin. "
    "Default: build/cm530/firmware.bin or build/qemu/firmware.elf from `make firmware` in a "
    "checkout, else the image shipped with snakebot.",
)

link_option: Decorator = click.option(
    "--link",
    metavar="PATH",
    help="Also create a symlink PATH to the pseudo-terminal, e.g. /tmp/ttyDXL.",
)


# --- waves ---------------------------------------------------------------------------------

WAVE = {
    "amplitude": ("-A", "30deg", "Serpenoid amplitude A (rad, or deg with 'deg')."),
    "omega": (
        "-w",
        "180deg",
        "Serpenoid temporal frequency omega (rad/s, or deg/s with 'deg'; pi expressions "
        "work); negative runs the wave backwards.",
    ),
    "delta": ("-d", "90deg", "Serpenoid phase step delta from one joint to the next (rad or deg)."),
}
"""Each serpenoid parameter's short flag, the demo's wave (the default where there is
one) and its help."""


def wave_options(*, required: bool = False) -> Decorator:
    """--amplitude/-A, --omega/-w and --delta/-d of a serpenoid: ``required``, or with
    the demo's wave as defaults."""
    return stack(
        *(
            click.option(
                f"--{name}",
                short,
                type=ANGLE,
                required=required,
                show_default=not required,
                help=text,
                # an explicit default of None counts as given: a required option has none
                **({} if required else {"default": default}),
            )
            for name, (short, default, text) in WAVE.items()
        )
    )


offset_option: Decorator = click.option(
    "--offset",
    type=ANGLE,
    default=0.0,
    show_default=True,
    help="Offset phi0 added to every joint's wave (rad or deg): bends the snake, which turns it.",
)

steer_option: Decorator = click.option(
    "--steer",
    type=ANGLE,
    default=0.0,
    show_default=True,
    help="Angle added to every joint, e.g. 10deg or 0.17 (radians unless suffixed with "
    "deg; up to about 150deg). Steers a snake by bending it.",
)

speed_option: Decorator = click.option(
    "--speed",
    type=NUMBER,
    default=1.0,
    show_default=True,
    help="Playback speed factor: 1 as generated, 2 twice as fast (0.004..4; the "
    "controller's Speed Scale).",
)

FRAME_PERIOD_MS = (1, 65535)
"""A gait table's frame period, whole milliseconds (its header's 16 bits)."""

rate_option: Decorator = click.option(
    "--rate",
    type=NumberType(1000 / FRAME_PERIOD_MS[1], 1000 / FRAME_PERIOD_MS[0]),
    default=50.0,
    show_default=True,
    help="Frame rate of the gait table in Hz (the frame period is rounded to whole ms).",
)

form_option: Decorator = click.option(
    "--form",
    type=click.Choice(["body", "world"]),
    help="Trident only: body-velocity inputs (default, the thesis's system (18)) or "
    "world-velocity inputs (system (11)); they differ in the brackets.",
)


# --- plans ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Goal:
    """A move to a pose as the command line gives it: --to, --from and the tolerances."""

    target: tuple[float, float, float]
    start: list[float] | None
    tolerance: float
    heading_tolerance: float

    def settings(self) -> dict[str, Any]:
        """The planners' keyword arguments for this goal besides the target."""
        return {
            "start": tuple(self.start) if self.start else None,
            "tolerance": self.tolerance,
            "heading_tolerance": self.heading_tolerance,
        }


def _goal_options() -> Decorator:
    """The options :func:`target_options` bundles (the planner's defaults loaded only
    where a command has them)."""
    from snakebot.model.plan.planner import DEFAULT_HEADING_TOLERANCE, DEFAULT_TOLERANCE

    return stack(
        click.option(
            "--to",
            "target",
            type=POSE,
            required=True,
            metavar="X,Y,THETA",
            help="Target body pose relative to the start pose: X along the start heading, Y to "
            "its left (the robot's length units), THETA counter-clockwise (rad, or deg with "
            "'deg'), e.g. 3,1,45deg.",
        ),
        click.option(
            "--from",
            "start",
            type=ANGLES,
            metavar="PHI1,...",
            help="Joint angles at the start, where the plan also ends (default: pi/3,-pi/3 for "
            "the 3-link snake, 0 for the others).",
        ),
        click.option(
            "--tolerance",
            type=NUMBER,
            default=DEFAULT_TOLERANCE,
            show_default=True,
            help="How near the end must be, as a fraction of the distance to the target "
            "(at least that fraction of a tenth of a body length).",
        ),
        click.option(
            "--heading-tolerance",
            type=ANGLE,
            default=DEFAULT_HEADING_TOLERANCE,
            show_default="2deg",
            help="How near the end heading must be (rad, or deg with 'deg').",
        ),
    )


def target_options(func: F) -> F:
    """--to, --from, --tolerance and --heading-tolerance of a move to a pose; the command
    takes ``goal`` (a :class:`Goal`)."""
    keys = ("target", "start", "tolerance", "heading_tolerance")
    return _goal_options()(_bundled(func, "goal", Goal, *keys))


# --- servo scans ---------------------------------------------------------------------------

ids_option: Decorator = click.option(
    "--ids",
    default="0-253",
    show_default=True,
    help="Servo IDs to look for, e.g. 0-253 or 1,2,5-7.",
)


def bauds_option(default: str | None = None, *, instead: str = "") -> Decorator:
    """--bauds: the rates to scan a servo bus at."""
    return click.option(
        "--bauds",
        default=default,
        show_default=default is not None,
        help=f"Rates to scan a servo bus at{instead}, comma-separated; 'common' for the "
        "AX-12's usual ones (1000000 ... 9615), 'all' for every rate an AX or MX servo is "
        "tabulated at (up to 3000000). The AX-12 leaves the factory at 1000000.",
    )


# --- output --------------------------------------------------------------------------------


def json_option(lines: str | None = None) -> Decorator:
    """--json: one JSON object on stdout (messages go to stderr), or for a command that
    prints as it goes, JSON Lines (``lines`` says what they are)."""
    return click.option(
        "--json",
        "as_json",
        is_flag=True,
        help=f"Print JSON Lines: {lines}."
        if lines
        else "Print the result as JSON on stdout (messages go to stderr).",
    )


def directory_option(*names: str, default: Path, what: str) -> Decorator:
    """A directory the command writes its files into (``what`` they are); made if need be."""
    return click.option(
        *names,
        "out_dir",
        type=click.Path(file_okay=False, path_type=Path),
        default=default,
        show_default=True,
        help=f"Directory for {what}.",
    )


def output_option(what: str, *, required: bool = True) -> Decorator:
    """--output, -o: the file the command writes (``what`` it is)."""
    return click.option("--output", "-o", type=OUTPUT_PATH, required=required, help=f"{what}.")


def plot_option(what: str) -> Decorator:
    """--plot: also draw ``what``, in the format its extension names."""
    return click.option(
        "--plot",
        type=PLOT_PATH,
        help=f"Also write a picture of {what} (PNG, or another format by the file's "
        "extension: .svg, .pdf, ...).",
    )


def video_option(what: str) -> Decorator:
    """``--video FILE`` (a video of ``what``) and ``--size WxH``, as the parameters
    ``video`` and ``video_size``."""

    # imported here: only the commands that film load the video module
    from snakebot.plots.video import DEFAULT_SIZE, SUFFIXES

    def decorate(func: F) -> F:
        func = click.option(
            "--size",
            "video_size",
            type=SizeType(),
            default=f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}",
            show_default=True,
            help="The video's width x height in pixels (even numbers).",
        )(func)
        return click.option(
            "--video",
            type=OutputPathType(lambda: tuple(s.lstrip(".") for s in SUFFIXES)),
            help=f"Write a video of {what}: {VIDEO_WORDS}.",
        )(func)

    return decorate


FOXGLOVE_RATE_HZ = 50.0
"""How often a command sends the robot's state to Foxglove (at most: a command that
samples slower sends each sample)."""


class EndpointType(click.ParamType):
    """``[HOST:]PORT`` as (host, port), loopback unless a host is given; the live extra
    is checked here, before the command starts any work."""

    name = "[HOST:]PORT"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        from snakebot.extras import MissingExtraError, require
        from snakebot.workflows.foxglove import FoxgloveOptionError, parse_endpoint

        if isinstance(value, tuple):
            return value
        try:
            endpoint = parse_endpoint(str(value))
        except FoxgloveOptionError as exc:
            self.fail(str(exc), param, ctx)
        try:
            require("foxglove", "--foxglove", extra="live")
        except MissingExtraError as exc:
            self.fail(str(exc), param, ctx)
        return endpoint


def foxglove_option(what: str) -> Decorator:
    """``--foxglove [HOST:]PORT`` (the parameter ``foxglove``: (host, port) or None):
    stream ``what`` live to Foxglove."""
    return click.option(
        "--foxglove",
        type=EndpointType(),
        help=f"Stream to Foxglove, live, {what} (open ws://HOST:PORT in Foxglove; "
        "`snakebot foxglove-layout` writes a layout for it): /joint_states, /tf, "
        "/snakebot/servos (goals, loads, errors), /snakebot/controller, up to "
        f"{FOXGLOVE_RATE_HZ:g} times a second. Listens on 127.0.0.1 unless a HOST is given "
        "(0.0.0.0: every interface); PORT 0 takes a free one.",
    )


MIN_LOOK_INTERVAL_S = 0.02
"""The shortest time between two looks at the controller (--interval)."""


def look_options(default_interval: float, *, mode: str = "", until: str = "Ctrl-C") -> Decorator:
    """--duration and --interval of a command that looks at the controller again and
    again, as the parameters ``duration`` and ``interval``; ``mode`` says in their help
    when they apply (e.g. ``with --port``), ``until`` what ends it without --duration."""
    when = f", {mode}" if mode else ""
    return stack(
        click.option(
            "--duration",
            type=NumberType(0),
            default=None,
            help=f"Stop after this many seconds{when} (default: until {until}).",
        ),
        click.option(
            "--interval",
            type=NumberType(MIN_LOOK_INTERVAL_S),
            default=default_interval,
            show_default=True,
            help=f"Seconds between looks at the controller{when}.",
        ),
    )
