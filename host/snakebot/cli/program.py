"""`snakebot program build` and `snakebot program show`: controller programs, a list of
table, serpenoid and periodic-input segments the controller runs on its own."""

from __future__ import annotations

from pathlib import Path

import click

from snakebot.cli.options import json_option, output_option, robot_option
from snakebot.cli.output import echo_json
from snakebot.formats.program.describe import describe_program
from snakebot.formats.program.files import read_program, write_program
from snakebot.model.program_spec import build_program, load_spec


@click.group("program")
def program() -> None:
    """Controller programs: up to 64 segments (play table frames, run the serpenoid, run a
    periodic input) the controller runs one after the other, each starting where the
    previous one was heading (protocol/program.md).

    \b
        snakebot program build plan.toml --robot snake5 -o plan.prog
        snakebot program show plan.prog
        snakebot upload plan.prog --port /dev/ttyUSB0
        snakebot play --port /dev/ttyUSB0
    """


@program.command("build")
@click.argument("spec", type=click.Path(dir_okay=False, path_type=Path))
@output_option("The program file to write (.prog)")
@robot_option("The robot whose joints it drives", otherwise="the spec's `robot`")
@json_option()
def build(spec: Path, output: Path, robot: str | None, as_json: bool) -> None:
    """Build a program from SPEC, a TOML (or .json) file listing segments in SI units:

    \b
        robot = "snake5"
        period_ms = 20                  # one program step
        table = "walk.gait"             # optional: frames for table segments
        [[segment]]
        kind = "serpenoid"              # amplitude, omega, delta, offset (rad, rad/s)
        amplitude = 0.5
        omega = 3.14
        delta = 1.05
        duration = 4.0                  # seconds
        [[segment]]
        kind = "periodic"               # per joint: rate (rad/s), sin, cos (rad)
        omega = 3.14
        sin = [0.3, 0.3, 0.3, 0.3, 0.3]
        duration = 2.0
        [[segment]]
        kind = "table"                  # first, count, repetitions
        repetitions = 2

    The program is checked as the controller will check it (joint limits including where
    earlier segments left each joint, the servo's speed); nothing is written otherwise.
    """
    built = build_program(load_spec(spec), robot, base=spec.parent)
    write_program(output, built)
    summary = describe_program(built, output)
    if echo_json(as_json, summary):
        return
    click.echo(
        f"wrote {output}: {summary['bytes']} bytes, {len(built.segments)} segments for "
        f"{len(built.joints)} joints, {built.total_steps} steps of {built.period_ms} ms "
        f"({built.duration_s:.2f} s)."
    )


@program.command("show")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@json_option()
def show(file: Path, as_json: bool) -> None:
    """Show the program in FILE (from `snakebot program build`): its joints and segments,
    in SI units."""
    prog = read_program(file)
    summary = describe_program(prog, file)
    if echo_json(as_json, summary):
        return
    click.echo(
        f"{file}: {summary['bytes']} bytes, CRC-32 {summary['crc']}, a step every "
        f"{prog.period_ms} ms, {prog.total_steps} steps ({prog.duration_s:.2f} s)"
    )
    ids = ", ".join(str(j.servo_id) for j in prog.joints)
    click.echo(f"joints: servo {ids}")
    for k, seg in enumerate(summary["segments"]):
        fields = ", ".join(f"{key} {value}" for key, value in seg.items() if key != "kind")
        click.echo(f"  {k + 1:2d}. {seg['kind']}: {fields}")
