"""``snakebot plan``: a gait table, or a controller program, that takes the robot to a
target pose."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import click

from snakebot.cli.controller.link import controller_id_option
from snakebot.cli.output import dumps
from snakebot.cli.params import ANGLE, ANGLES, NUMBER, OUTPUT_PATH, controller_port
from snakebot.facts.boards import TABLE_CAPACITY
from snakebot.model.gait.values import ExpressionError, parse_angle, parse_number
from snakebot.model.plan import Unreachable
from snakebot.model.plan.planner import (
    DEFAULT_BOARD,
    DEFAULT_CAPACITY,
    DEFAULT_HEADING_TOLERANCE,
    DEFAULT_TOLERANCE,
)

#: Exit status when no plan reaches the target: a runtime failure, not bad input.
EXIT_UNREACHABLE = 1


class PoseType(click.ParamType):
    """X,Y,THETA: two numbers in the robot's length units, and an angle (rad or deg)."""

    name = "x,y,theta"

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> tuple[float, float, float]:
        if isinstance(value, tuple):
            return value
        parts = str(value).split(",")
        if len(parts) != 3 or not all(p.strip() for p in parts):
            self.fail(f"{value!r} is not X,Y,THETA: give three comma-separated values", param, ctx)
        try:
            return (parse_number(parts[0]), parse_number(parts[1]), parse_angle(parts[2]))
        except ExpressionError as exc:
            self.fail(str(exc), param, ctx)


POSE = PoseType()

#: The longest --capacity worth reading (a number of bytes or a board's name).
MAX_CAPACITY_CHARS = 32


class CapacityType(click.ParamType):
    """BYTES or a board's name: the table capacity a plan is made for, in bytes."""

    name = "capacity"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        if isinstance(value, int):
            return value
        text = str(value).strip().lower()
        if text in TABLE_CAPACITY:
            return TABLE_CAPACITY[text]
        if len(text) > MAX_CAPACITY_CHARS or not (text.isascii() and text.isdigit()):
            boards = ", ".join(sorted(TABLE_CAPACITY))
            shown = text if len(text) <= MAX_CAPACITY_CHARS else text[:MAX_CAPACITY_CHARS] + "..."
            self.fail(
                f"{shown!r} is neither a whole number of bytes nor a board ({boards})", param, ctx
            )
        return int(text)

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        return "BYTES|" + "|".join(sorted(TABLE_CAPACITY))


CAPACITY = CapacityType()

TO_OPTION = click.option(
    "--to",
    "target",
    type=POSE,
    required=True,
    metavar="X,Y,THETA",
    help="target body pose relative to the start pose: X along the start heading, Y to "
    "its left (the robot's length units), THETA counter-clockwise (rad, or deg with "
    "'deg'), e.g. 3,1,45deg",
)
FROM_OPTION = click.option(
    "--from",
    "start",
    type=ANGLES,
    metavar="PHI1,...",
    help="joint angles at the start, where the plan also ends (default: pi/3,-pi/3 for "
    "the 3-link snake, 0 for the others)",
)
TOLERANCE_OPTIONS = (
    click.option(
        "--tolerance",
        type=NUMBER,
        default=DEFAULT_TOLERANCE,
        show_default=True,
        help="how near the end must be, as a fraction of the distance to the target "
        "(at least that fraction of a tenth of a body length)",
    ),
    click.option(
        "--heading-tolerance",
        type=ANGLE,
        default=DEFAULT_HEADING_TOLERANCE,
        show_default="2deg",
        help="how near the end heading must be (rad, or deg with 'deg')",
    ),
)


def tolerance_options(f: Any) -> Any:
    for option in reversed(TOLERANCE_OPTIONS):
        f = option(f)
    return f


def unreachable(exc: Unreachable) -> None:
    """Report a target no plan reaches: one line, exit status 1."""
    click.echo(f"error: {exc}", err=True)
    raise SystemExit(EXIT_UNREACHABLE)


@click.command("plan")
@click.argument("robot", metavar="ROBOT")
@TO_OPTION
@FROM_OPTION
@tolerance_options
@click.option(
    "--output",
    "-o",
    type=OUTPUT_PATH,
    help="the gait table to write (FILE.json gets the metadata), or with a .prog suffix "
    "the controller program (on-board generators: a few hundred bytes); without it the "
    "plan is only reported",
)
@click.option(
    "--plot",
    type=click.Path(dir_okay=False, path_type=Path),
    help="also write a PNG of the joints and the body's path (needs -o)",
)
@click.option(
    "--capacity",
    type=CAPACITY,
    help="the largest table (or program) the plan may take, in bytes or as a board's "
    f"({', '.join(f'{b}: {n}' for b, n in sorted(TABLE_CAPACITY.items()))} bytes) "
    f"[default: {DEFAULT_BOARD}'s {DEFAULT_CAPACITY}, the smallest board's, so that a "
    "plan made without asking the controller plays on every board]",
)
@click.option(
    "--port",
    "-p",
    callback=controller_port("snakebot sim serve"),
    help="ask the controller on this port (its PC link, e.g. /dev/ttyUSB0, or the "
    "pseudo-terminal of `snakebot sim serve`) for its Table Capacity and plan for that; "
    "instead of --capacity",
)
@controller_id_option
@click.option("--json", "as_json", is_flag=True, help="print the report as JSON")
def plan_command(
    robot: str,
    target: tuple[float, float, float],
    start: list[float] | None,
    tolerance: float,
    heading_tolerance: float,
    output: Path | None,
    plot: Path | None,
    capacity: int | None,
    port: str | None,
    controller_id: int,
    as_json: bool,
) -> None:
    """Plan a gait table that takes ROBOT (snake3, trident, snake5 or a .toml) from rest
    to a target pose, for `snakebot upload` and `play`.

    \b
    How: the joints move from the start to a hub configuration, run one closed joint
    loop k times and come back. A loop through the hub moves the body by the same pose
    wherever it is (the system is driftless and the same everywhere on the floor), so k
    loops reach the target when one loop makes its k-th root: the same circular arc,
    a k-th of the way. The loop (two harmonics per joint) is fitted to that root by
    least squares with the exact motion integrated by the C core, the Lie brackets'
    leading order corrected all along the way. For a snake the first guess is a
    serpenoid wave; the plan keeps inside the joint limits and is timed to the servos'
    speed; its table, rounded to ticks and played as the controller plays it, is checked
    to end within the tolerance.

    With -o FILE.prog the plan is a controller program instead (protocol/program.md):
    the start held, the straight joint moves as offset rates; for N-link snakes two arcs
    of serpenoid waves, each at its own offset (A, delta and the offsets fitted to the
    target); for the trident and the 3-link snake the loops as one periodic-input block
    (one harmonic per joint, fitted with its hub); where no such loop reaches the target
    (the 3-link snake, often), the table plan's loop is played as a table segment. The
    program's goals, as the controller rounds them at every step, are integrated and
    must end within the tolerance; the route is fitted again to make up for the error a
    few times, and a program still outside is not written (exit 1). --json reports its
    size in bytes.

    The plan fits the table capacity it is made for: the smallest board's unless
    --capacity names another (the CM-530 holds the largest tables, so a longer way goes
    in one plan there) or --port asks the controller it is for. Routes of few loops are
    tried first (at every hub the nominal count, then twice as many, up to what the
    capacity holds). When no plan inside the limits and the capacity reaches the target,
    the command says so and exits with status 1; nothing is written.

    \b
    Example:
      snakebot plan trident --to 2,1,30deg -o go.gait
      snakebot sim predict go.gait --ideal
      snakebot plan snake3 --to 12,0,0 --capacity cm530 -o far.gait
      snakebot plan snake3 --to 12,0,0 --port /dev/ttyUSB0 -o far.gait
      snakebot plan trident --to 1,0.5,30deg -o go.prog
      snakebot upload go.prog --port /dev/ttyUSB0 && snakebot play --port /dev/ttyUSB0
    """
    from snakebot.model.plan import make_plan
    from snakebot.model.plan.program import plan_program
    from snakebot.model.robots import load_robot

    if plot is not None and output is None:
        raise click.UsageError("--plot needs -o FILE: the plot is drawn from the written table")
    as_program = output is not None and output.suffix == ".prog"
    if as_program and plot is not None:
        raise click.UsageError(
            "--plot draws a gait table: for a program, use "
            "`snakebot sim predict FILE.prog --plot PNG`"
        )
    if capacity is not None and port is not None:
        raise click.UsageError(
            "--capacity and --port both set the capacity planned for: give one of them"
        )
    chosen = load_robot(robot)
    if port is not None:
        capacity = controller_capacity(port, controller_id)
    try:
        plan = (plan_program if as_program else make_plan)(
            chosen,
            target,
            start=tuple(start) if start else None,
            tolerance=tolerance,
            heading_tolerance=heading_tolerance,
            capacity=DEFAULT_CAPACITY if capacity is None else capacity,
        )
    except Unreachable as exc:
        unreachable(exc)
        return
    if as_program:
        assert output is not None
        _write_program(plan, output, as_json)
        return
    summary = plan.summary()
    if output is not None:
        from snakebot.formats.gaittable import sidecar_path, write_gait

        table = plan.gait.gait_table()
        write_gait(output, table)
        summary.update(file=str(output), metadata_file=str(sidecar_path(output)))
        if plot is not None:
            from snakebot.plots.gait import plot_gait

            summary["plot"] = str(plot_gait(table, plot))
    for warning in summary["warnings"]:
        click.echo(f"warning: {warning['message']}", err=True)
    if as_json:
        click.echo(dumps(summary, indent=2))
        return
    _print(summary)


def controller_capacity(port: str, controller_id: int) -> int:
    """The Table Capacity of the controller on ``port`` (its PC link at the firmware's
    rate): the largest table or program it takes."""
    from snakebot.facts.boards import PC_LINK_BAUD
    from snakebot.link.controller.client import ControllerClient
    from snakebot.link.controller.upload import CAPACITY as CAPACITY_REGISTER

    with ControllerClient.open(port, PC_LINK_BAUD, controller_id) as ctl:
        return ctl.read(CAPACITY_REGISTER)[CAPACITY_REGISTER]


def _write_program(plan: Any, output: Path, as_json: bool) -> None:
    """Write the plan's program (its goals end within the tolerance) and report it."""
    from snakebot.formats.program.files import write_program

    write_program(output, plan.program)
    s = plan.summary()
    s["file"] = str(output)
    if as_json:
        click.echo(dumps(s, indent=2))
        return
    kinds = ", ".join(f"{seg['kind']} ({seg['steps']} steps)" for seg in s["segments"])
    hubs = "; ".join(", ".join(f"{math.degrees(v):.1f}" for v in h) for h in s["hubs_rad"])
    click.echo(
        f"program for {s['robot']}: {s['loops']} {s['loop_kind']} loops through "
        f"hub(s) ({hubs}) deg, {s['program_bytes']} bytes of the {s['capacity_bytes']} "
        "planned for, a step every "
        f"{s['step_period_ms']} ms ({s['duration_s']:.2f} s): {kinds}"
    )
    _print_pose(s, "the program's goals as the controller rounds them")
    click.echo(f"wrote {s['file']}")


def _print_pose(s: dict[str, Any], how: str) -> None:
    t, f, e = s["target"], s["predicted_final"], s["error"]
    click.echo(
        f"  target     x = {t['x']: .4f}  y = {t['y']: .4f}  theta = "
        f"{math.degrees(t['theta']): .2f} deg"
    )
    click.echo(
        f"  predicted  x = {f['x']: .4f}  y = {f['y']: .4f}  theta = "
        f"{math.degrees(f['theta']): .2f} deg ({how})"
    )
    click.echo(
        f"  error {e['position']:.4g} (tolerance {e['position_tolerance']:.4g}), heading "
        f"{math.degrees(e['heading_rad']):.3f} deg (tolerance "
        f"{math.degrees(e['heading_tolerance_rad']):.2f} deg)"
    )


def _print(s: dict[str, Any]) -> None:
    click.echo(
        f"plan for {s['robot']}: {s['loops']} loops through hub "
        f"({', '.join(f'{math.degrees(v):.1f}' for v in s['hub_rad'])}) deg, "
        f"{s['frames']} frames every {s['frame_period_ms']} ms ({s['duration_s']:.2f} s), "
        f"{s['table_bytes']} bytes of the {s['capacity_bytes']} planned for"
    )
    _print_pose(s, "the table as the controller plays it")
    if "file" in s:
        click.echo(f"wrote {s['file']} and {s['metadata_file']}")
    if "plot" in s:
        click.echo(f"plot written to {s['plot']}")
