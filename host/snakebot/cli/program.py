"""`snakebot program build` and `snakebot program show`: controller programs, a list of
table, serpenoid and periodic-input segments the controller runs on its own."""

from __future__ import annotations

import zlib
from pathlib import Path
from typing import Any

import click

from snakebot.cli.output import dumps
from snakebot.cli.params import OUTPUT_PATH
from snakebot.formats.program import PeriodicSegment, Program, SerpenoidSegment, TableSegment
from snakebot.formats.program.files import read_program, write_program
from snakebot.model.program_spec import build_program, load_spec

MRAD = 1000.0


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
@click.option(
    "-o",
    "--output",
    type=OUTPUT_PATH,
    required=True,
    help="The program file to write (.prog).",
)
@click.option(
    "--robot",
    help="The robot whose joints it drives (snake5, ... or a .toml file); "
    "overrides the spec's `robot`.",
)
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
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
        sin = [0.3, 0.3, 0.3, 0.3]
        duration = 2.0
        [[segment]]
        kind = "table"                  # first, count, repetitions
        repetitions = 2

    The program is checked as the controller will check it (joint limits including where
    earlier segments left each joint, the servo's speed); nothing is written otherwise.
    """
    built = build_program(load_spec(spec), robot, base=spec.parent)
    write_program(output, built)
    summary = _summary(built, output)
    if as_json:
        click.echo(dumps(summary))
        return
    click.echo(
        f"wrote {output}: {summary['bytes']} bytes, {len(built.segments)} segments for "
        f"{len(built.joints)} joints, {built.total_steps} steps of {built.period_ms} ms "
        f"({built.duration_s:.2f} s)."
    )


@program.command("show")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the program as JSON.")
def show(file: Path, as_json: bool) -> None:
    """Show the program in FILE (from `snakebot program build`): its joints and segments,
    in SI units."""
    prog = read_program(file)
    summary = _summary(prog, file)
    if as_json:
        click.echo(dumps(summary))
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


def _summary(prog: Program, path: Path) -> dict[str, Any]:
    data = prog.encode()
    return {
        "file": str(path),
        "bytes": len(data),
        "crc": f"0x{zlib.crc32(data):08x}",
        "period_ms": prog.period_ms,
        "steps": prog.total_steps,
        "duration_s": prog.duration_s,
        "joints": [
            {"id": j.servo_id, "zero": j.zero, "min": j.low, "max": j.high, "reverse": j.reverse}
            for j in prog.joints
        ],
        "frames": len(prog.frames),
        "segments": [_segment(prog, s) for s in prog.segments],
    }


def _segment(prog: Program, seg: object) -> dict[str, Any]:
    seconds = getattr(seg, "steps", 0) * prog.period_ms / 1000.0
    if isinstance(seg, TableSegment):
        return {
            "kind": "table",
            "first": seg.first,
            "count": seg.count,
            "repetitions": seg.repetitions,
            "duration_s": seconds,
        }
    if isinstance(seg, SerpenoidSegment):
        return {
            "kind": "serpenoid",
            "amplitude": seg.amp_mrad / MRAD,
            "omega": seg.omega_mrad_s / MRAD,
            "delta": seg.delta_mrad / MRAD,
            "offset": seg.phi0_mrad / MRAD,
            "duration_s": seconds,
        }
    assert isinstance(seg, PeriodicSegment)
    rows = prog.blocks[seg.block]
    return {
        "kind": "periodic",
        "omega": seg.omega_mrad_s / MRAD,
        "rate": [r[0] / MRAD for r in rows],
        "sin": [r[1] / MRAD for r in rows],
        "cos": [r[2] / MRAD for r in rows],
        "duration_s": seconds,
    }
