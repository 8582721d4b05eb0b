"""``snakebot model``: the kinematic models of a robot (vector fields, brackets, rank)."""

from __future__ import annotations

from typing import Any

import click
import numpy as np

from snakebot.cli.options import form_option, json_option, robot_argument
from snakebot.cli.output import dumps, echo_json
from snakebot.cli.params import ANGLES
from snakebot.extras import require
from snakebot.model.kinematics import default_form
from snakebot.model.kinematics.model import singular_reason
from snakebot.model.reports import describe_robot, field_report, lie_report, uses_lie_jets
from snakebot.model.robots import load_robot


@click.group("model")
def model() -> None:
    """Kinematic models of a robot: its description, control vector fields, Lie brackets
    and controllability (docs/models.md has the conventions)."""


@model.command("info")
@robot_argument
@json_option()
def info(robot: str, as_json: bool) -> None:
    """Show a robot description: geometry, friction, and each joint's servo.

    ROBOT is a built-in robot (snake3, trident, snake5, car) or the path of a robot .toml
    file.

    Example: snakebot model info snake5
    """
    rb = load_robot(robot)
    data = describe_robot(rb)
    if echo_json(as_json, data, indent=2):
        return
    click.echo(f"{rb.name}: {rb.description or rb.kind} ({rb.source})")
    geometry = ", ".join(
        f"{k} = {v:g}" if not isinstance(v, list) else f"{k} = ({', '.join(f'{a:g}' for a in v)})"
        for k, v in data["geometry"].items()
    )
    click.echo(f"  geometry: {geometry}")
    f = rb.friction
    click.echo(
        f"  friction: lateral mu = {f.lateral:g}, rolling C_rr = {f.rolling:g}, axle "
        f"{f.axle_nm:g} N m; wheel loads {', '.join(f'{v:.3g}' for v in rb.wheel_loads_n())} N"
    )
    click.echo(f"  servo: {rb.servo_model}, max {rb.max_speed_rad_s:.2f} rad/s")
    for j in data["joints"]:
        click.echo(
            f"  {j['name']}: ID {j['servo_id']}, zero tick {j['zero_tick']}, sign "
            f"{j['sign']:+d}, {j['min_deg']:g}..{j['max_deg']:g} deg "
            f"(ticks {j['ticks'][0]}..{j['ticks'][1]})"
        )


def _fmt(values: Any) -> str:
    return "(" + ", ".join(f"{v + 0.0: .9g}" for v in values) + ")"


@model.command("fields")
@robot_argument
@click.option(
    "--at",
    "at",
    type=ANGLES,
    metavar="Q1,Q2,...",
    help="the configuration q = x,y,theta,phi1,...; each a number, a pi expression "
    "or a 'deg' value, e.g. 0,0,0,pi/3,-pi/3 or 0,0,0,60deg,-60deg",
)
@form_option
@click.option(
    "--depth",
    type=int,
    metavar="D",
    help="bracket depth for snakes and the car (default 3, at most 8; a 16-link snake "
    "takes about 3 s at depth 5): a Lyndon basis of brackets up to D and the growth "
    "vector to D",
)
@json_option()
@click.option(
    "--symbolic",
    is_flag=True,
    help="print the fields as expressions (sympy) instead of values at q; "
    "--at is then not needed (the 3-link snake takes about 5 s to simplify)",
)
def fields_command(
    robot: str,
    at: list[float] | None,
    form: str | None,
    depth: int | None,
    as_json: bool,
    symbolic: bool,
) -> None:
    """The control vector fields g1.. and their Lie brackets h1.. at a configuration,
    with the rank at each step of the filtration (the growth vector), det G* and whether
    q is singular.

    det G* (the fields side by side) is printed from its closed form: l^6 / det B^4 for
    the 3-link snake (det B = 4 l sin((phi1-phi2)/2) cos(phi1/2) cos(phi2/2), zero where
    phi1 = phi2 or a joint is at +-pi), 3 sqrt(3) r^2 / (2 l^6) for the trident. It is
    never zero where the fields exist, so the growth vector is exact however near the
    singular set q is; the condition number of G* (unit columns) beside it says how near.

    ROBOT is snake3, trident, snake5, car, or a robot file: fields are defined where the
    non-slip constraints determine the motion. Brackets follow [X, Y] = DY X - DX Y;
    fields come in the thesis's order (3-link: h1 = [g1,g2], h2 = [g1,h1],
    h3 = [g2,h1]; trident: h1 = [g1,g2], h2 = [g1,g3], h3 = [g2,g3]).

    An N-link snake (any N from 3 to 16) has two control fields: g1 moves joint 1 at
    unit rate and g2 joint 2, with the other of the two still; the body and joints 3..
    do what the N wheel constraints then require. Its brackets (and the car's, or the
    3-link snake's with --depth) are a Lyndon basis named by their expressions,
    e.g. [g1,[g1,g2]] and [[g1,g2],g2] (= -h3 for 3 links), computed to any --depth
    from exact derivatives. Their growth vector is exact to depth 3 (snakes: the
    first five coordinates are the 3-link snake's, whose det G* is never zero; the car:
    det(S, D, R, T) = 1/(L^2 cos^4 Phi)); deeper ranks are numeric, with the condition
    number, and flagged where double precision cannot decide them. The car (thesis,
    chapter 1) has q = (x, y, theta, Phi), steering S, drive D, R = [S,D],
    T = [R,D]: growth (2, 3, 4).

    Example: snakebot model fields snake3 --at 0,0,0,pi/3,-pi/3
    """
    rb = load_robot(robot)
    jets = uses_lie_jets(rb, depth)
    if symbolic and (depth is not None or rb.kind == "snake" and rb.links != 3):
        raise click.UsageError(
            "--symbolic is available for snake3, the trident and the car (no --depth)"
        )
    if depth is not None and not jets:
        raise click.UsageError(
            "--depth applies to snakes and the car: the trident's filtration is complete "
            "at depth 2 (growth (3, 6))"
        )
    if symbolic:
        _print_symbolic(rb, form or default_form(rb), as_json)
        return
    n = len(rb.state_names)
    if at is None:
        raise click.UsageError("give the configuration with --at (or ask for --symbolic)")
    if len(at) != n:
        raise click.BadParameter(
            f"{rb.name} has {n} coordinates ({', '.join(rb.state_names)}): give {n} values, "
            f"got {len(at)}",
            param_hint="--at",
        )
    if jets and form is not None:
        raise click.UsageError("--form applies to the trident only")
    data = lie_report(rb, at, depth or 3) if jets else field_report(rb, at, form)
    if as_json:
        click.echo(dumps(data, indent=2))
    elif jets:
        _print_lie(rb, data)
    else:
        _print_fields(rb, data)


def _print_fields(rb: Any, data: dict[str, Any]) -> None:
    used_form = data["form"]
    inputs = "joint-velocity" if used_form == "joint" else f"{used_form}-velocity"
    click.echo(f"{rb.name} ({inputs} inputs) at q = {_fmt(data['q'])}")
    click.echo(f"  coordinates: ({', '.join(rb.state_names)})")
    if data["fields"] is None:
        click.echo(
            f"  singular: yes (det B = {data['det_b']:.3g}): the 3-link snake's fields are "
            f"undefined where det B = 0; here {data['singular_where']}"
        )
        return
    for name, values in data["fields"].items():
        click.echo(f"  {name:3} = {_fmt(values)}")
    growth = tuple(data["growth"]) if data["growth"] is not None else None
    click.echo(
        f"  growth vector: {growth}   det G* = {data['det']:.9g}   condition number "
        f"{data['condition']:.3g}   singular: {'yes' if data['singular'] else 'no'}"
    )
    _echo_joint_driven(data["joint_driven"])


def _echo_joint_driven(data: dict[str, Any] | None) -> None:
    if data is None or not data["near_singular"]:
        return
    where = (
        "at a singular configuration (the wheel axles meet in one point or are parallel)"
        if data["rcond"] == 0
        else f"near a singular configuration (condition number {1 / data['rcond']:.3g})"
    )
    click.echo(f"  warning: driven by its joints, as the servos drive it, q is {where}")


def _print_lie(rb: Any, data: dict[str, Any]) -> None:
    click.echo(f"{rb.name} (inputs: {data['inputs']}) at q = {_fmt(data['q'])}")
    click.echo(f"  coordinates: ({', '.join(rb.state_names)})")
    if data["fields"] is None:
        where = (
            "the steering is at +-90 degrees (tan Phi has a pole)"
            if rb.kind == "car"
            else f"the first three links' constraints do not determine the body: "
            f"{singular_reason(rb, np.array(data['q']))}"
        )
        click.echo(f"  singular: yes: {where}")
        return
    expressions = data["aliases"]
    names = list(data["fields"])
    labels = [f"{n} = {expressions[n]}" if n in expressions else n for n in names]
    width = max(len(label) for label in labels)
    for name, label in zip(names, labels, strict=True):
        click.echo(f"  {label:{width}} = {_fmt(data['fields'][name])}")
    exact = data["growth_exact_to_depth"]
    click.echo(
        f"  growth vector: {tuple(data['growth'])} (exact to depth {exact})   condition number "
        f"{data['condition']:.3g}   singular: no"
    )
    if not data["growth_reliable"]:
        click.echo(
            f"  warning: past depth {exact} the ranks are numeric, and at this condition "
            "number double precision cannot decide them (q is too near the singular set)"
        )
    _echo_joint_driven(data["joint_driven"])


def _print_symbolic(rb: Any, form: str, as_json: bool) -> None:
    require("sympy", "--symbolic")
    from snakebot.model.symbolic.display import field_expressions

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
    params = ", ".join(str(p) for p in ex.model.params if p.name in ("l", "r", "L"))
    inputs = "steering S, drive D" if rb.kind == "car" else f"{form} inputs"
    click.echo(f"{rb.name} fields ({inputs}), symbolic in {params}; x, y in {ex.frame}")
    for field_name, comps in ex.components.items():
        click.echo(f"{field_name}:")
        for coord, expr in zip(names, comps, strict=True):
            click.echo(f"  {coord:6} {expr}")
