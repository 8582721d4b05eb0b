"""``snakebot gait``: generate gait tables (serpenoid, field-following) and inspect them;
``gait search`` is in ``search``.

May import: as the ``cli`` layer (every layer below it)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from snakebot.cli.output import dumps
from snakebot.cli.params import ANGLE, ANGLES, NUMBER, OUTPUT_PATH, PLOT_PATH, NumberType
from snakebot.extras import require
from snakebot.formats.gaittable import read_gait, sidecar_path, write_gait
from snakebot.model.gait import Gait, field_gait, serpenoid
from snakebot.model.robots import load_robot

RATE = NumberType(0, low_open=True)
RATE_HELP = "frame rate of the table in Hz (the frame period is rounded to whole ms)"
OUT_HELP = "the gait table file to write (FILE.json gets the metadata)"


@click.group("gait")
def gait() -> None:
    """Generate gait tables for the controller, and inspect them.

    Every generated gait is checked against the robot's joint limits and its servos'
    maximum speed before anything is written. Angles are radians unless suffixed
    with 'deg' (rates: rad/s, or deg/s with 'deg'); pi expressions work: pi/4.

    A gait whose joint motion passes near a singular configuration (wheel axles
    meeting in one point or all parallel: the wheel model's condition number above
    100, reciprocal below 0.01) gets a warning on stderr and in the JSON "warnings":
    its predicted body motion there is hypersensitive to rounding and friction."""


PLOT_OPTION = click.option(
    "--plot",
    type=PLOT_PATH,
    help="also write a PNG: each joint, and x, y, theta of the predicted body, against "
    "time (as the thesis's figures), beside the body's path",
)


def _write(g: Gait, out: Path, as_json: bool, plot: Path | None = None) -> None:
    table = g.gait_table()
    write_gait(out, table)
    summary = {
        "file": str(out),
        "metadata_file": str(sidecar_path(out)),
        "bytes": table.size,
        **g.summary(),
    }
    if plot is not None:
        from snakebot.plots.gait import plot_gait

        summary["plot"] = str(plot_gait(table, plot))
    if as_json:
        click.echo(dumps(summary, indent=2))
        return
    click.echo(
        f"wrote {out} ({table.frame_count} frames x {table.joint_count} joints every "
        f"{table.frame_period_ms} ms, {'loop' if table.loop else 'played once'}, "
        f"{table.size} bytes) and {sidecar_path(out)}"
    )
    _print_motion(summary)
    if plot is not None:
        click.echo(f"plot written to {summary['plot']}")


def _print_motion(meta: dict[str, Any]) -> None:
    def line(label: str, m: dict[str, Any]) -> None:
        click.echo(
            f"  {label:34} dx = {m['dx']: .6f}  dy = {m['dy']: .6f}  "
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
    if "note" in meta["table"]:
        click.echo(f"  note: {meta['table']['note']}")
    for warning in meta.get("warnings", []):
        click.echo(f"warning: {warning['message']}", err=True)


@gait.command("serpenoid")
@click.argument("robot", metavar="ROBOT")
@click.option("--amplitude", "-A", type=ANGLE, required=True, help="A (rad or deg)")
@click.option(
    "--omega",
    "-w",
    type=ANGLE,
    required=True,
    help="W: temporal frequency (rad/s, or deg/s with 'deg')",
)
@click.option(
    "--delta",
    "-d",
    type=ANGLE,
    required=True,
    help="D: phase shift between consecutive joints (rad or deg)",
)
@click.option(
    "--offset",
    type=ANGLE,
    default=0.0,
    show_default=True,
    help="P0: offset added to every joint (turns the snake)",
)
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
@click.option("--rate", type=RATE, default=50.0, show_default=True, help=RATE_HELP)
@click.option("--output", "-o", type=OUTPUT_PATH, required=True, help=OUT_HELP)
@PLOT_OPTION
@click.option("--json", "as_json", is_flag=True, help="print the summary as JSON")
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
    """A serpenoid gait: phi_k(t) = A sin(W t + (k-1) D + S) + P0 on every joint k.

    ROBOT is a snake (snake3, snake5, or a .toml file). W is adjusted slightly so the
    gait spans a whole number of frames (the summary shows the value used). The summary
    gives the body motion predicted from the continuous gait and from the table as
    written (rounded to ticks, interpolated linearly as the controller plays it).

    Example: snakebot gait serpenoid snake5 -A 30deg -w 180deg -d 90deg --cycles 2 -o s.gait

    The thesis's example phi1 = cos(-2 pi^2/3 t + pi^2), phi2 = cos(-2 pi^2/3 t - 2 pi^2)
    (cos x = sin(x + pi/2)) is
    -A 1 -w "-2*pi**2/3" -d "-3*pi**2" --phase "pi**2+pi/2" --cycles 1.
    """
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
@click.argument("robot", metavar="ROBOT")
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
    type=NumberType(0, low_open=True),
    help="largest relative error per loop against the "
    "bracket prediction; picks A (default 0.05 unless --amplitude is given)",
)
@click.option(
    "--start",
    type=ANGLES,
    metavar="PHI1,...",
    help="joint angles at the start "
    "(default: the thesis's pi/3,-pi/3 for the 3-link snake, 0 for the trident)",
)
@click.option(
    "--form",
    type=click.Choice(["body", "world"]),
    help="trident: body- (default) or world-velocity inputs",
)
@click.option("--rate", type=RATE, default=50.0, show_default=True, help=RATE_HELP)
@click.option("--output", "-o", type=OUTPUT_PATH, required=True, help=OUT_HELP)
@PLOT_OPTION
@click.option("--json", "as_json", is_flag=True, help="print the summary as JSON")
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
@click.argument("file", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option(
    "--plot",
    type=PLOT_PATH,
    help="also write a plot of the joint angles and the predicted body path "
    "(PNG, or another format by the file's extension: .svg, .pdf, ...)",
)
@click.option("--json", "as_json", is_flag=True, help="print the summary as JSON")
def show(file: Path, plot: Path | None, as_json: bool) -> None:
    """Summarise a gait table file (and its FILE.json metadata), optionally as a plot.

    Two checksums are shown: the header CRC, stored in the table's header over the rest
    of the table, and the file CRC-32 of all its bytes, which is what `snakebot upload`
    and `snakebot monitor` call the table's CRC-32 (the controller's Table CRC).
    """
    table = read_gait(file)
    meta = table.metadata
    computed = {
        "file": str(file),
        "bytes": table.size,
        "header_crc": f"0x{table.crc:08X}",
        "file_crc32": f"0x{table.image_crc:08X}",
        "joint_ids": list(table.joint_ids),
        "limits": [list(x) for x in table.limits],
        "frames": table.frame_count,
        "frame_period_ms": table.frame_period_ms,
        "loop": table.loop,
        "duration_s": table.duration_ms / 1000.0,
    }
    # The metadata adds what the table cannot say (the gait, its predictions); what the
    # table's bytes say wins over anything the metadata file claims.
    hidden = ("path", "table_path", "joints")
    summary = {**{k: v for k, v in meta.items() if k not in hidden}, **computed}
    if plot is not None:
        require("matplotlib", "--plot")
        from snakebot.plots.gait import plot_gait

        summary["plot"] = str(plot_gait(table, plot))
    if as_json:
        click.echo(dumps(summary, indent=2))
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


from snakebot.cli.gait.search import search_command  # noqa: E402 - after the group exists

gait.add_command(search_command)
