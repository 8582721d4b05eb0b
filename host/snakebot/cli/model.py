"""``snakebot model``: the kinematic models of a robot (vector fields, brackets, rank)."""

from __future__ import annotations

import math
from typing import Any

import click
import numpy as np

from snakebot.cli.output import dumps
from snakebot.cli.params import ANGLES
from snakebot.kinematics import default_form, field_model, fields
from snakebot.robots import load_robot


@click.group("model")
def model() -> None:
    """Kinematic models of a robot: its description, control vector fields, Lie brackets
    and controllability (docs/models.md has the conventions)."""


@model.command("info")
@click.argument("robot", metavar="ROBOT")
@click.option("--json", "as_json", is_flag=True, help="print JSON instead of text")
def info(robot: str, as_json: bool) -> None:
    """Show a robot description: geometry, friction, and each joint's servo.

    ROBOT is a built-in robot (snake3, trident, snake5) or the path of a robot .toml file.
    """
    rb = load_robot(robot)
    data: dict[str, Any] = {
        "robot": rb.name,
        "kind": rb.kind,
        "description": rb.description,
        "source": rb.source,
        "geometry": (
            {"links": rb.links, "half_link": rb.l}
            if rb.kind == "snake"
            else {
                "base_radius": rb.r,
                "arm_length": rb.l,
                "alphas_deg": [math.degrees(a) for a in rb.alphas],
            }
        ),
        "friction": {"c_n": rb.c_n, "c_t": rb.c_t},
        "servo": {"model": rb.servo_model, "max_speed_rad_s": rb.max_speed_rad_s},
        "joints": [
            {
                "name": j.name,
                "servo_id": j.servo_id,
                "zero_tick": j.zero_tick,
                "sign": j.sign,
                "min_deg": math.degrees(j.min_rad),
                "max_deg": math.degrees(j.max_rad),
                "ticks": list(j.tick_range),
            }
            for j in rb.joints
        ],
    }
    if as_json:
        click.echo(dumps(data, indent=2))
        return
    click.echo(f"{rb.name}: {rb.description or rb.kind} ({rb.source})")
    geometry = ", ".join(
        f"{k} = {v:g}" if not isinstance(v, list) else f"{k} = ({', '.join(f'{a:g}' for a in v)})"
        for k, v in data["geometry"].items()
    )
    click.echo(f"  geometry: {geometry}")
    click.echo(
        f"  friction: c_n = {rb.c_n:g}, c_t = {rb.c_t:g}"
        + ("  (ideal wheels)" if rb.c_t == 0 else "")
    )
    click.echo(f"  servo: {rb.servo_model}, max {rb.max_speed_rad_s:.2f} rad/s")
    for j in data["joints"]:
        click.echo(
            f"  {j['name']}: ID {j['servo_id']}, zero tick {j['zero_tick']}, sign "
            f"{j['sign']:+d}, {j['min_deg']:g}..{j['max_deg']:g} deg "
            f"(ticks {j['ticks'][0]}..{j['ticks'][1]})"
        )


def _fmt(values: np.ndarray) -> str:
    return "(" + ", ".join(f"{v + 0.0: .9g}" for v in values) + ")"


@model.command("fields")
@click.argument("robot", metavar="ROBOT")
@click.option(
    "--at",
    "at",
    type=ANGLES,
    metavar="Q1,Q2,...",
    help="the configuration q = x,y,theta,phi1,...; each a number, a pi expression "
    "or a 'deg' value, e.g. 0,0,0,pi/3,-pi/3 or 0,0,0,60deg,-60deg",
)
@click.option(
    "--form",
    type=click.Choice(["body", "world"]),
    help="trident only: body-velocity inputs (default, the thesis's system (18)) "
    "or world-velocity inputs (system (11)); they differ in the brackets",
)
@click.option("--json", "as_json", is_flag=True, help="print JSON instead of text")
@click.option(
    "--symbolic",
    is_flag=True,
    help="print the fields as expressions (sympy) instead of values at q; "
    "--at is then not needed (the 3-link snake takes about 20 s to simplify)",
)
def fields_command(
    robot: str, at: list[float] | None, form: str | None, as_json: bool, symbolic: bool
) -> None:
    """The control vector fields g1.. and their Lie brackets h1.. at a configuration,
    with the rank at each step of the filtration (the growth vector), det G* and whether
    q is singular.

    ROBOT is snake3 or trident (or a file describing a 3-link snake or a trident):
    fields are defined where the non-slip constraints determine the body's motion.
    Brackets follow [X, Y] = DY X - DX Y; fields come in the thesis's order
    (3-link: h1 = [g1,g2], h2 = [g1,h1], h3 = [g2,h1]; trident: h1 = [g1,g2],
    h2 = [g1,g3], h3 = [g2,g3]).

    Example: snakebot model fields snake3 --at 0,0,0,pi/3,-pi/3
    """
    rb = load_robot(robot)
    kind = field_model(rb)
    n = 3 + rb.n_joints
    used_form = form or default_form(rb)
    if symbolic:
        _print_symbolic(rb, used_form, as_json)
        return
    if at is None:
        raise click.UsageError("give the configuration with --at (or ask for --symbolic)")
    if len(at) != n:
        raise click.BadParameter(
            f"{rb.name} has {n} coordinates ({', '.join(rb.state_names)}): give {n} values, "
            f"got {len(at)}",
            param_hint="--at",
        )
    fs = fields(rb, np.array(at), form)
    data = {
        "robot": rb.name,
        "form": used_form,
        "q": [float(v) for v in at],
        "fields": None
        if fs.values is None
        else {name: (fs[name] + 0.0).tolist() for name in fs.names},
        "growth": None if fs.growth is None else list(fs.growth),
        "det": fs.det,
        "singular": fs.singular,
    }
    if kind == "snake3":
        data["det_b"] = fs.det_b
    if as_json:
        click.echo(dumps(data, indent=2))
        return
    inputs = "joint-velocity" if used_form == "joint" else f"{used_form}-velocity"
    click.echo(f"{rb.name} ({inputs} inputs) at q = {_fmt(np.array(at))}")
    click.echo(f"  coordinates: ({', '.join(rb.state_names)})")
    if fs.values is None:
        click.echo(
            f"  singular: yes (det B = {fs.det_b:.3g}): the 3-link snake's fields are "
            "undefined where phi1 = phi2"
        )
        return
    for name in fs.names:
        click.echo(f"  {name:3} = {_fmt(fs[name])}")
    click.echo(
        f"  growth vector: {fs.growth}   det G* = {fs.det:.9g}   singular: "
        f"{'yes' if fs.singular else 'no'}"
    )


def _print_symbolic(rb: Any, form: str, as_json: bool) -> None:
    from snakebot.symbolic.display import field_expressions

    ex = field_expressions(rb, form if rb.kind == "trident" else "body")
    names = [str(s) for s in ex.model.q]
    if as_json:
        click.echo(
            dumps(
                {
                    "robot": rb.name,
                    "form": form,
                    "coordinates": names,
                    "frame": ex.frame,
                    "fields": {k: [str(c) for c in v] for k, v in ex.components.items()},
                },
                indent=2,
            )
        )
        return
    params = ", ".join(str(p) for p in ex.model.params if p.name in ("l", "r"))
    click.echo(f"{rb.name} fields ({form} inputs), symbolic in {params}; x, y in {ex.frame}")
    for field_name, comps in ex.components.items():
        click.echo(f"{field_name}:")
        for coord, expr in zip(names, comps, strict=True):
            click.echo(f"  {coord:6} {expr}")
