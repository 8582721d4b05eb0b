"""``snakebot model``: the kinematic models of a robot (vector fields, brackets, rank)."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import click
import numpy as np

from snakebot.cli.output import dumps
from snakebot.cli.params import ANGLES
from snakebot.extras import require
from snakebot.model.gait.common import NEAR_SINGULAR_RCOND
from snakebot.model.kinematics import body_velocity, default_form, field_model, fields
from snakebot.model.kinematics.lie import LieFields, lie_fields, lie_model
from snakebot.model.kinematics.model import singular_reason
from snakebot.model.robots import load_robot


@click.group("model")
def model() -> None:
    """Kinematic models of a robot: its description, control vector fields, Lie brackets
    and controllability (docs/models.md has the conventions)."""


@model.command("info")
@click.argument("robot", metavar="ROBOT")
@click.option("--json", "as_json", is_flag=True, help="print JSON instead of text")
def info(robot: str, as_json: bool) -> None:
    """Show a robot description: geometry, friction, and each joint's servo.

    ROBOT is a built-in robot (snake3, trident, snake5, car) or the path of a robot .toml
    file.
    """
    rb = load_robot(robot)
    data: dict[str, Any] = {
        "robot": rb.name,
        "kind": rb.kind,
        "description": rb.description,
        "source": rb.source,
        "geometry": {
            "snake": lambda: {"links": rb.links, "half_link": rb.l},
            "car": lambda: {"wheelbase": rb.l},
            "trident": lambda: {
                "base_radius": rb.r,
                "arm_length": rb.l,
                "alphas_deg": [math.degrees(a) for a in rb.alphas],
            },
        }[rb.kind](),
        "friction": {
            "lateral": rb.friction.lateral,
            "rolling": rb.friction.rolling,
            "axle_nm": rb.friction.axle_nm,
            "wheel_loads_n": [float(v) for v in rb.wheel_loads_n()],
        },
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
@click.option(
    "--depth",
    type=int,
    metavar="D",
    help="bracket depth for snakes and the car (default 3, at most 8; a 16-link snake "
    "takes about 3 s at depth 5): a Lyndon basis of brackets up to D and the growth "
    "vector to D",
)
@click.option("--json", "as_json", is_flag=True, help="print JSON instead of text")
@click.option(
    "--symbolic",
    is_flag=True,
    help="print the fields as expressions (sympy) instead of values at q; "
    "--at is then not needed (the 3-link snake takes about 20 s to simplify)",
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
    jets = rb.kind == "car" or (rb.kind == "snake" and (rb.links != 3 or depth is not None))
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
    if at is not None and len(at) != n:
        raise click.BadParameter(
            f"{rb.name} has {n} coordinates ({', '.join(rb.state_names)}): give {n} values, "
            f"got {len(at)}",
            param_hint="--at",
        )
    if jets:
        if form is not None:
            raise click.UsageError("--form applies to the trident only")
        assert at is not None
        _print_lie(rb, lie_fields(lie_model(rb), np.array(at), depth or 3), as_json)
        return
    kind = field_model(rb)
    used_form = form or default_form(rb)
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
        "condition": fs.condition,
        "singular": fs.singular,
        "joint_driven": _joint_driven(rb, np.array(at)),
    }
    if kind == "snake3":
        data["det_b"] = fs.det_b
        if fs.singular:
            data["singular_where"] = singular_reason(rb, np.array(at))
    if as_json:
        click.echo(dumps(data, indent=2))
        return
    inputs = "joint-velocity" if used_form == "joint" else f"{used_form}-velocity"
    click.echo(f"{rb.name} ({inputs} inputs) at q = {_fmt(np.array(at))}")
    click.echo(f"  coordinates: ({', '.join(rb.state_names)})")
    if fs.values is None:
        click.echo(
            f"  singular: yes (det B = {fs.det_b:.3g}): the 3-link snake's fields are "
            f"undefined where det B = 0; here {data['singular_where']}"
        )
        return
    for name in fs.names:
        click.echo(f"  {name:3} = {_fmt(fs[name])}")
    click.echo(
        f"  growth vector: {fs.growth}   det G* = {fs.det:.9g}   condition number "
        f"{fs.condition:.3g}   singular: {'yes' if fs.singular else 'no'}"
    )
    _echo_joint_driven(data["joint_driven"])


def _joint_driven(rb: Any, q: np.ndarray) -> dict[str, Any] | None:
    """How well the joints, driven as the servos drive them, determine the body at q
    by geometry alone: the reciprocal condition number of the wheels' no-slip rows, as
    the quasi-static model sees them with free rolling (None for the car). With rolling
    resistance the model is defined there too, but the motion then depends on friction."""
    if rb.kind not in ("snake", "trident"):
        return None
    free = replace(rb.friction, rolling=0.0, axle_nm=0.0)
    rcond = body_velocity(rb, q, np.zeros(rb.n_joints), free).rcond
    return {"rcond": rcond, "near_singular": rcond < NEAR_SINGULAR_RCOND}


def _echo_joint_driven(data: dict[str, Any] | None) -> None:
    if data is None or not data["near_singular"]:
        return
    where = (
        "at a singular configuration (the wheel axles meet in one point or are parallel)"
        if data["rcond"] == 0
        else f"near a singular configuration (condition number {1 / data['rcond']:.3g})"
    )
    click.echo(f"  warning: driven by its joints, as the servos drive it, q is {where}")


def _print_lie(rb: Any, lf: LieFields, as_json: bool) -> None:
    inputs = "steering S, drive D" if rb.kind == "car" else "joint rates dphi1 (g1), dphi2 (g2)"
    data = {
        "robot": rb.name,
        "form": "car" if rb.kind == "car" else "joint",
        "q": [float(v) for v in lf.q],
        "coordinates": list(rb.state_names),
        "inputs": inputs,
        "depth": max(lf.depths),
        "fields": None
        if lf.values is None
        else {name: (lf[name] + 0.0).tolist() for name in lf.names},
        "depths": dict(zip(lf.names, lf.depths, strict=True)),
        "aliases": {v: k for k, v in lf.aliases.items()},
        "growth": None if lf.growth is None else list(lf.growth),
        "growth_exact_to_depth": len(lf.exact),
        "growth_reliable": lf.ranks_reliable,
        "condition": lf.condition,
        "singular": lf.singular,
        "joint_driven": _joint_driven(rb, lf.q),
    }
    if lf.singular and rb.kind == "snake":
        data["singular_where"] = singular_reason(rb, lf.q)
    if as_json:
        click.echo(dumps(data, indent=2))
        return
    click.echo(f"{rb.name} (inputs: {inputs}) at q = {_fmt(lf.q)}")
    click.echo(f"  coordinates: ({', '.join(rb.state_names)})")
    if lf.values is None:
        where = (
            "the steering is at +-90 degrees (tan Phi has a pole)"
            if rb.kind == "car"
            else f"the first three links' constraints do not determine the body: "
            f"{singular_reason(rb, lf.q)}"
        )
        click.echo(f"  singular: yes: {where}")
        return
    expressions = {v: k for k, v in lf.aliases.items()}
    labels = [f"{n} = {expressions[n]}" if n in expressions else n for n in lf.names]
    width = max(len(label) for label in labels)
    for name, label in zip(lf.names, labels, strict=True):
        click.echo(f"  {label:{width}} = {_fmt(lf[name])}")
    exact = len(lf.exact)
    click.echo(
        f"  growth vector: {lf.growth} (exact to depth {exact})   condition number "
        f"{lf.condition:.3g}   singular: no"
    )
    if not lf.ranks_reliable:
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
