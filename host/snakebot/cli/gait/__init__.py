"""``snakebot gait``: generate gait tables (serpenoid, field-following) and inspect them;
``gait search`` is in ``search``.

May import: as the ``cli`` layer (every layer below it)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from snakebot.cli.lazy import LazyCommand, LazyGroup
from snakebot.cli.options import (
    form_option,
    json_option,
    offset_option,
    output_option,
    plot_option,
    rate_option,
    robot_argument,
    stack,
    wave_options,
)
from snakebot.cli.output import echo_json
from snakebot.cli.params import ANGLE, ANGLES, EXISTING_INPUT, NUMBER, NumberType, bare_angle_hint
from snakebot.extras import require

if TYPE_CHECKING:
    from snakebot.formats.gaittable import GaitTable
    from snakebot.model.gait import Gait
# the tables, the robots and the generators load when a command runs: --help needs none

MIN_FIELD_TOLERANCE = 1e-3
"""The smallest --tolerance of `gait field`: it already asks for a 100-second table that
moves the robot a ten-thousandth of its length; 1e-300 divided by zero."""


SUBCOMMANDS = {
    "search": LazyCommand(
        "snakebot.cli.gait.search:search_command",
        "Search serpenoid gaits phi_k(t) = A sin(omega t + (k-1) delta) + offset for ROBOT.",
    )
}
"""The sub-commands in modules of their own, imported when run (``cli.lazy``)."""


@click.group("gait", cls=LazyGroup, lazy=SUBCOMMANDS)
def gait() -> None:
    """Generate gait tables for the controller, and inspect them.

    Every generated gait is checked against the robot's joint limits and its servos'
    maximum speed before anything is written. Angles are radians unless suffixed
    with 'deg' (rates: rad/s, or deg/s with 'deg'); pi expressions work: pi/4.

    A gait whose joint motion passes near a singular configuration (wheel axles
    meeting in one point or all parallel: the wheel model's condition number above
    100, reciprocal below 0.01) gets a warning on stderr and in the JSON "warnings":
    its predicted body motion there is hypersensitive to rounding and friction."""


PLOT_WHAT = (
    "each joint, and x, y, theta of the predicted body, against time (as the thesis's "
    "figures), beside the body's path"
)

table_output_options = stack(
    rate_option,
    output_option("The gait table file to write (FILE.json gets the metadata)"),
    plot_option(PLOT_WHAT),
    json_option(),
)
"""--rate, --output, --plot and --json of the commands that make a gait table."""


def _write(g: Gait, out: Path, as_json: bool, plot: Path | None = None) -> None:
    from snakebot.formats.gaittable import sidecar_path
    from snakebot.model.gait.files import save_gait

    table, summary = save_gait(g, out)
    _plot(table, plot, summary)
    if echo_json(as_json, summary, indent=2):
        return
    click.echo(
        f"wrote {out} ({table.frame_count} frames x {table.joint_count} joints every "
        f"{table.frame_period_ms} ms, {'loop' if table.loop else 'played once'}, "
        f"{table.size} bytes) and {sidecar_path(out)}"
    )
    _print_motion(summary)
    if plot is not None:
        click.echo(f"plot written to {summary['plot']}")


def _plot(table: GaitTable, plot: Path | None, summary: dict[str, Any]) -> None:
    """With --plot, draw ``table`` there and name the file in ``summary``."""
    if plot is not None:
        require("matplotlib", "--plot")
        from snakebot.plots.gait import plot_gait

        summary["plot"] = str(plot_gait(table, plot))


def _print_motion(meta: dict[str, Any]) -> None:
    unit = meta.get("length_unit", "u")

    def line(label: str, m: dict[str, Any]) -> None:
        click.echo(
            f"  {label:34} dx = {m['dx']: .6f} {unit}  dy = {m['dy']: .6f} {unit}  "
            f"dtheta = {m['dtheta']: .6f} rad"
        )

    frame = meta.get("frame", "start pose frame")
    click.echo(f"predicted body motion over {meta.get('duration_s', 0):.3f} s ({frame}):")
    line("continuous gait:", meta["predicted"])
    line("table as written (ticks, linear):", meta["table"])
    for key, label in (
        ("second_order", "bracket prediction tau X(q0):"),
        ("first_order", "first order tau X(q0):"),
    ):
        if key in meta:
            line(label, meta[key])
    if meta.get("length_legend"):
        click.echo(f"  ({meta['length_legend']})")
    if "note" in meta["table"]:
        click.echo(f"  note: {meta['table']['note']}")
    for warning in meta.get("warnings", []):
        click.echo(f"warning: {warning['message']}", err=True)


@gait.command("serpenoid")
@robot_argument
@wave_options(required=True)
@offset_option
@click.option(
    "--phase",
    type=ANGLE,
    default=0.0,
    show_default=True,
    help="S: start phase of joint 1 at t = 0 (rad or deg; pi expressions work)",
)
@click.option(
    "--cycles",
    type=NumberType(0, low_open=True),
    required=True,
    help="C: number of cycles; a whole number makes a looping table",
)
@table_output_options
@bare_angle_hint
def serpenoid_command(
    robot: str,
    amplitude: float,
    omega: float,
    delta: float,
    offset: float,
    phase: float,
    cycles: float,
    rate: float,
    output: Path,
    plot: Path | None,
    as_json: bool,
) -> None:
    """A serpenoid gait: phi_k(t) = A sin(omega t + (k-1) delta + S) + phi0 on every
    joint k.

    ROBOT is a snake (snake3, snake5, or a .toml file). omega is adjusted slightly so the
    gait spans a whole number of frames (the summary shows the value used). The summary
    gives the body motion predicted from the continuous gait and from the table as
    written (rounded to ticks, interpolated linearly as the controller plays it).

    Example: snakebot gait serpenoid snake5 -A 30deg -w 180deg -d 90deg --cycles 2 -o s.gait

    The thesis's example phi1 = cos(-2 pi^2/3 t + pi^2), phi2 = cos(-2 pi^2/3 t - 2 pi^2)
    (cos x = sin(x + pi/2)) is
    -A 1 -w "-2*pi**2/3" -d "-3*pi**2" --phase "pi**2+pi/2" --cycles 1.
    """
    from snakebot.model.gait.serpenoid import serpenoid
    from snakebot.model.robots import load_robot

    g = serpenoid(
        load_robot(robot),
        amplitude,
        omega,
        delta,
        offset=offset,
        phase=phase,
        cycles=cycles,
        rate_hz=rate,
    )
    _write(g, output, as_json, plot)


@gait.command("field")
@robot_argument
@click.option(
    "--field",
    "expression",
    required=True,
    metavar="EXPR",
    help="a field or a combination: g1, h1, 2*g1-h3, (2*g1-h3)/2, g3+2*h1",
)
@click.option(
    "--duration",
    type=NUMBER,
    help="T: follow EXPR for T units of its flow "
    "parameter (the motion of T * EXPR to first order); the gait itself runs as "
    "fast as the servos allow. Default for combinations with brackets: 1, or the "
    "longest the table holds at the --tolerance (the summary's flow_parameter)",
)
@click.option(
    "--periods", type=click.IntRange(min=1), help="K: number of input loops (bracket terms only)"
)
@click.option(
    "--amplitude",
    "-A",
    type=ANGLE,
    help="loop amplitude A (each loop moves pi A^2 along its bracket)",
)
@click.option(
    "--omega",
    "-w",
    type=ANGLE,
    help="loop frequency (rad/s); default: as fast "
    "as the servos allow, at least 16 frames per loop",
)
@click.option(
    "--tolerance",
    type=NumberType(MIN_FIELD_TOLERANCE, 1),
    help="largest relative error per loop against the bracket prediction; picks A "
    f"(default 0.05 unless --amplitude is given; {MIN_FIELD_TOLERANCE:g} to 1: a smaller "
    "one makes loops too small to move the robot)",
)
@click.option(
    "--start",
    type=ANGLES,
    metavar="PHI1,...",
    help="joint angles at the start "
    "(default: the thesis's pi/3,-pi/3 for the 3-link snake, 0 for the trident)",
)
@form_option
@table_output_options
@bare_angle_hint
def field_command(
    robot: str,
    expression: str,
    duration: float | None,
    periods: int | None,
    amplitude: float | None,
    omega: float | None,
    tolerance: float | None,
    start: list[float] | None,
    form: str | None,
    rate: float,
    output: Path,
    plot: Path | None,
    as_json: bool,
) -> None:
    """A gait that follows a control vector field or a combination of fields and Lie
    brackets (snake3, trident).

    Direct fields (g...) are followed with constant inputs. Bracket terms (h...) are
    made by periodic inputs over whole periods: a loop in the inputs of [g_i, g_j]
    moves pi A^2 [g_i, g_j] to second order (the 3-link snake's h2, h3 are third-order
    brackets and use a two-frequency input). Smaller loops are more accurate (the error
    shrinks about linearly with A), so --tolerance picks A and the number of loops.

    Example: snakebot gait field trident --field 2*g1-h3 --duration 0.2 --tolerance 0.2 -o x.gait

    The thesis's combinations (2*g1-h3, g3+2*h1, g2+h2/2, g1-h3 for the trident) work
    as they are: without --duration the tolerance (default 0.05) sets the loop size and
    the gait follows the field for as long as the table allows, up to 1 unit.
    """
    from snakebot.model.gait.field import field_gait
    from snakebot.model.robots import load_robot

    g = field_gait(
        load_robot(robot),
        expression,
        duration=duration,
        periods=periods,
        amplitude=amplitude,
        omega=omega,
        tolerance=tolerance,
        start=tuple(start) if start else None,
        form=form,
        rate_hz=rate,
    )
    _write(g, output, as_json, plot)


@gait.command("show")
@click.argument("file", type=EXISTING_INPUT)
@plot_option("the joint angles and the predicted body path")
@json_option()
def show(file: Path, plot: Path | None, as_json: bool) -> None:
    """Summarise a gait table file (and its FILE.json metadata), optionally as a plot.

    Two checksums are shown: the header CRC, stored in the table's header over the rest
    of the table, and the file CRC-32 of all its bytes, which is what `snakebot upload`
    and `snakebot monitor` call the table's CRC-32 (the controller's Table CRC).

    \b
        snakebot gait show walk.gait
        snakebot gait show walk.gait --plot walk.png --json
    """
    from snakebot.formats.gaittable import describe_table, read_gait

    table = read_gait(file)
    meta = table.metadata
    summary = describe_table(file, table)
    _plot(table, plot, summary)
    if echo_json(as_json, summary, indent=2):
        return
    click.echo(
        f"{file}: {table.size} bytes, header CRC {summary['header_crc']}, "
        f"file CRC-32 {summary['file_crc32']}"
    )
    click.echo(
        f"  {table.frame_count} frames every {table.frame_period_ms} ms "
        f"({'loop' if table.loop else 'played once'}, {table.duration_ms / 1000:.3f} s)"
    )
    for jid, (lo, hi) in zip(table.joint_ids, table.limits, strict=True):
        column = table.frames[:, list(table.joint_ids).index(jid)]
        click.echo(
            f"  servo {jid}: ticks {int(column.min())}..{int(column.max())} (limits {lo}..{hi})"
        )
    if "gait" in meta:
        params = ", ".join(
            f"{k} = {_short(v)}" for k, v in meta.get("parameters", {}).items() if k != "segments"
        )
        click.echo(f"  {meta['gait']} gait for {meta.get('robot', '?')}: {params}")
    if "predicted" in meta and "table" in meta:
        _print_motion(meta)
    if plot is not None:
        click.echo(f"plot written to {summary['plot']}")


def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list) and all(isinstance(v, float) for v in value):
        return "(" + ", ".join(f"{v:.4g}" for v in value) + ")"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_short(v)}" for k, v in value.items()) + "}"
    return str(value)
