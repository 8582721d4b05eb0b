"""`snakebot robot`: bring a robot description and the real robot into agreement."""

from __future__ import annotations

from pathlib import Path

import click

from snakebot.cli.options import BusLink, bus_options
from snakebot.cli.output import dumps
from snakebot.cli.params import INPUT_PATH, OutputPathType
from snakebot.link.bus.calibrate import JOG_DEG, calibrate, updated_text, write_atomically
from snakebot.model.robots import BUILTIN_ROBOTS, load_robot, parse_robot
from snakebot.model.robots.loader import MAX_FILE_BYTES
from snakebot.model.robots.model import Joint
from snakebot.model.robots.template import robot_file_text
from snakebot.userfiles import OutputExists, check_output, read_bounded, write_atomic


@click.group("robot")
def robot() -> None:
    """Work on a robot description (a robot .toml): start one, calibrate it against the
    real robot, or export it for other tools."""


@robot.command("new")
@click.argument("file", metavar="FILE.toml", type=OutputPathType(lambda: ("toml",)))
@click.option(
    "--like",
    type=click.Choice(BUILTIN_ROBOTS),
    default="snake5",
    show_default=True,
    help="The built-in robot whose kind and values the file starts from.",
)
@click.option(
    "--links",
    type=int,
    metavar="N",
    help="For a snake: N links (N - 1 joints; each added joint as the last, its own servo ID).",
)
@click.option("--force", is_flag=True, help="Replace FILE if it exists.")
@click.option("--json", "as_json", is_flag=True, help="print JSON instead of text")
def new_command(file: Path, like: str, links: int | None, force: bool, as_json: bool) -> None:
    """Write a new robot description to FILE.toml, to edit for your robot: the values of a
    built-in robot, each key under a comment saying what it is and in what unit. An
    existing FILE is kept unless --force.

    Then measure your robot and change the geometry, set each joint's servo ID and
    limits (`snakebot robot calibrate` measures the zero ticks and signs), and check it
    with `snakebot model info FILE.toml`.

    \b
    Example: snakebot robot new my.toml --like snake5
    """
    text = robot_file_text(file.stem, like, links)
    try:
        write_atomic(file, text, replace=force)
    except OutputExists as exc:
        raise exc.about("force") from None
    described = parse_robot(text, source=str(file))
    if as_json:
        click.echo(dumps({"robot": str(file), "like": like, "joints": described.n_joints}))
        return
    joints = f"{described.n_joints} joint{'s' if described.n_joints != 1 else ''}"
    click.echo(
        f"wrote {file}: {described.kind} {described.name} with {joints} "
        f"(servo IDs {', '.join(str(i) for i in described.servo_ids)}), from {like}; edit it "
        f"for your robot, then check it with `snakebot model info {file}`"
    )


@robot.command("calibrate")
@click.argument("toml", metavar="ROBOT.toml", type=INPUT_PATH)
@bus_options
@click.option(
    "--yes",
    "-y",
    is_flag=True,
    help="Ask nothing: the snake already lies straight, and each joint keeps the sign in "
    "the file (its jog then only checks that the servo follows).",
)
def calibrate_command(toml: Path, bus: BusLink, as_json: bool, yes: bool) -> None:
    """Measure each joint's zero tick and sign on the real robot and write them into
    ROBOT.toml (its comments and layout are kept; the file is replaced in one step,
    and only if the result is a valid robot).

    Connect the servos through a bus adapter and power them. The command turns the
    torque off; you lay the snake straight on the floor and press Enter; each joint's
    position is read as its zero tick. Then each joint turns a little (about 10
    degrees) and back, and you say whether the link nearer the head turned
    counter-clockwise seen from above (sign 1) or clockwise (sign -1).

    \b
        snakebot robot calibrate my_snake.toml --port /dev/ttyUSB0
    """
    described = load_robot(toml)
    check_output(toml)  # written back at the end: refused now, not after the calibration
    text = read_bounded(toml, MAX_FILE_BYTES, "robot description").decode("utf-8")
    if not yes:
        click.echo(
            f"{described.name}: turning the torque off. Lay the snake straight (every link "
            "in one line), then press Enter.",
            err=as_json,
        )
        click.prompt("", default="", show_default=False, prompt_suffix="", err=as_json)

    def ask(joint: Joint) -> bool:
        return click.confirm(
            f"{joint.name} (servo {joint.servo_id}) turned about {JOG_DEG:g} degrees and back: "
            "did the link nearer the head turn counter-clockwise, seen from above?",
            err=as_json,
        )

    with bus.open() as client:
        found = calibrate(client, described, None if yes else ask)
    write_atomically(toml, updated_text(text, found))
    if as_json:
        click.echo(dumps({"robot": str(toml), "joints": [c.as_dict() for c in found]}))
        return
    for c in found:
        origin = "as you saw it" if c.asked else "kept from the file"
        click.echo(
            f"{c.name}: servo {c.servo_id}, zero tick {c.zero_tick}, sign {c.sign:+d} "
            f"({origin}; the jog turned it {c.moved_ticks:+d} ticks)"
        )
    click.echo(f"Wrote {toml}.")


@robot.command("export")
@click.argument("robot_name", metavar="ROBOT")
@click.option(
    "--urdf",
    type=OutputPathType(lambda: ("urdf",)),
    help="Write the robot as URDF here (ROS tools, RViz, Foxglove's 3-D panel, MuJoCo).",
)
@click.option(
    "--mjcf",
    type=OutputPathType(lambda: ("xml",)),
    help="Write the physics world's MuJoCo model here (.xml).",
)
@click.option("--json", "as_json", is_flag=True, help="print JSON instead of text")
def export_command(robot_name: str, urdf: Path | None, mjcf: Path | None, as_json: bool) -> None:
    """Export ROBOT for other tools: the links with their masses and inertias, the servo
    joints with their limits, and the wheels, as the physics world builds them (from the
    robot's [physics] table).

    ROBOT is a built-in robot (snake3, snake5, trident) or a robot .toml file. The URDF's
    root link is `base` (the body's pose is the odometry); the MJCF has the floor, the
    wheel-floor friction and position servos on the joints.

    \b
        snakebot robot export snake5 --urdf snake5.urdf --mjcf snake5.xml
    """
    if urdf is None and mjcf is None:
        raise click.UsageError("name a file to write: --urdf FILE, --mjcf FILE or both")
    from snakebot.sim.physics.export import export_mjcf, export_urdf

    described = load_robot(robot_name)
    written = {}
    if urdf is not None:
        written["urdf"] = str(write_atomic(urdf, export_urdf(described)))
    if mjcf is not None:
        written["mjcf"] = str(write_atomic(mjcf, export_mjcf(described)))
    if as_json:
        click.echo(dumps({"robot": described.name, **written}))
        return
    for kind, path in written.items():
        click.echo(f"wrote {path} ({kind.upper()} of {described.name})")
