"""``snakebot plan``: a gait table, or a controller program, that takes the robot to a
target pose."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import click

from snakebot.cli.errors import message
from snakebot.cli.options import (
    CONTROLLER_PORT,
    ControllerLink,
    Goal,
    controller_id_option,
    json_option,
    output_option,
    plot_option,
    port_option,
    robot_argument,
    target_options,
)
from snakebot.cli.output import dumps
from snakebot.cli.params import CAPACITY
from snakebot.cli.troubleshooting import error_line
from snakebot.extras import require
from snakebot.facts.boards import TABLE_CAPACITY, smallest_board
from snakebot.model.plan import PlanRequest, Unreachable
from snakebot.model.plan.cycle_plan import MAX_PLAYS
from snakebot.model.plan.cycle_plan import MAX_PLAYS_BOTH as BOTH_PLAYS
from snakebot.model.plan.planner import DEFAULT_BOARD, DEFAULT_CAPACITY
from snakebot.sim.physics.select import require_world

#: The worlds a plan is made for: the emulator's two, or both at once.
PLAN_WORLDS = ("kinematic", "mujoco", "both")
#: Exit status when no plan reaches the target: a runtime failure, not bad input.
EXIT_UNREACHABLE = 1


def unreachable(exc: Unreachable) -> None:
    """Report a target no plan reaches: one line led by the options it is about, exit
    status 1."""
    click.echo(error_line(message(exc, click.get_current_context(silent=True))), err=True)
    raise SystemExit(EXIT_UNREACHABLE)


@click.command("plan")
@robot_argument
@target_options
@output_option(
    "The gait table to write (FILE.json gets the metadata), or with a .prog suffix the "
    "controller program (on-board generators: a few hundred bytes); without it the plan "
    "is only reported",
    required=False,
)
@plot_option("the joints and the body's path (needs -o)")
@click.option(
    "--capacity",
    type=CAPACITY,
    help="The largest table (or program) the plan may take, in bytes or as a board's "
    f"({', '.join(f'{b}: {n}' for b, n in sorted(TABLE_CAPACITY.items()))} bytes) "
    f"[default: the controller's own with --port, else the {DEFAULT_BOARD}'s "
    f"{DEFAULT_CAPACITY}, the robot's board's; a plan for a smaller board, e.g. "
    f"--capacity {smallest_board()}, plays on every board].",
)
@port_option(
    CONTROLLER_PORT,
    purpose="Ask the controller on this port for its Table Capacity and plan for that "
    "(instead of --capacity)",
    required=False,
)
@controller_id_option
@click.option(
    "--world",
    type=click.Choice(PLAN_WORLDS),
    default="kinematic",
    show_default=True,
    help="The world the table is made and checked in. kinematic: the loop table above, "
    "checked in the quasi-static world. mujoco (N-link snakes, a table only): whole "
    "serpenoid cycles, played open loop in MuJoCo and corrected by the miss until they "
    f"end within the tolerance there (up to {MAX_PLAYS} plays, 1..20 s of CPU where the "
    "loop plan takes a few). both (N-link snakes, a table only): serpenoid cycles solved "
    "to end within the tolerance in the quasi-static world and within twice it in MuJoCo "
    f"(up to {BOTH_PLAYS} MuJoCo plays, 5..60 s of CPU; measured to meet both on "
    "straight ways only, docs/goto.md).",
)
@json_option()
def plan_command(
    robot: str,
    goal: Goal,
    output: Path | None,
    plot: Path | None,
    capacity: int | None,
    port: str | None,
    controller_id: int,
    world: str,
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

    The table (or program) is also played on the robot's modelled servos, which lag
    it under the body's load, until they come to rest (--json: servo_check). A snake
    of more than three links has more wheels than its body has freedoms: how far it
    goes depends on how the wheels share the slip, so the report adds where the table
    ends with half and twice the rolling resistance (--json: friction_sensitivity).
    Where either leaves the tolerance, the plan warns that its end played open loop is
    not to be trusted (--json: a warning of kind open_loop, with the numbers): steer in
    closed loop with `snakebot sim goto` instead.

    The plan fits the table capacity it is made for: the controller's own when --port
    asks the controller it is for, else --capacity (a board's or a number of bytes), else
    the CM-530's, the robot's board (it holds the largest tables, so a longer way goes in
    one plan there; --capacity qemu plans for the smaller QEMU board, whose table every
    board takes). Routes of few loops are
    tried first (at every hub the nominal count, then twice as many, up to what the
    capacity holds). When no plan inside the limits and the capacity reaches the target,
    the command says so and exits with status 1; nothing is written.

    With --world mujoco an N-link snake's plan is made for MuJoCo instead, where the
    loops above end tens to hundreds of tolerances off: the joints move to a serpenoid
    wave (the one `sim goto` drives), play whole cycles, each at its own steering offset,
    forwards or backwards, and move back. The cycles are planned by a car model of one
    cycle, the model learns each cycle's motion from the first plays of the table in
    MuJoCo, and then the offsets and the wave's lag between joints (the length of a cycle)
    are corrected by the end's miss (Broyden's method) until the table ends within the
    tolerance in MuJoCo (--json: world, plays); a plan that does not converge is not
    written (exit 1). `snakebot sim predict PLAN.gait --world mujoco` ends where the plan
    says. The plan is for MuJoCo's body and floor: where the same table ends in the
    quasi-static world is reported (--json: quasi_static), with an open_loop warning when
    it is outside the tolerance.

    With --world both an N-link snake's plan of serpenoid cycles (no reversals) is solved
    for both worlds at once: its table must end within the tolerance in the quasi-static
    world and within twice it in MuJoCo, each played open loop (--json: quasi_static,
    mujoco). Routes of few long cycles are tried first, since the worlds part by a share
    of the way played. A table that no play brings within both bounds is not written
    (exit 1): the message gives the nearest one's error in each world.

    \b
    Example:
      snakebot plan trident --to 2,1,30deg -o go.gait
      snakebot plan snake5 --to 0.3,0.1,20deg --world mujoco -o go5.gait
      snakebot sim predict go5.gait --world mujoco
      snakebot plan snake5 --to 0.3,0,0 --world both -o both5.gait
      snakebot sim predict go.gait --ideal
      snakebot plan snake3 --to 12,0,0 -o far.gait            # the CM-530's table
      snakebot plan trident --to 2,1,30deg --capacity qemu -o small.gait
      snakebot plan snake3 --to 12,0,0 --port /dev/ttyUSB0 -o far.gait
      snakebot plan trident --to 1,0.5,30deg -o go.prog
      snakebot upload go.prog --port /dev/ttyUSB0 && snakebot play --port /dev/ttyUSB0
    """
    require("scipy", "planning", extra="plan")
    require_world("mujoco" if world == "both" else world)
    if plot is not None:
        require("matplotlib", "--plot")
    from snakebot.model.plan import Plan
    from snakebot.model.plan.files import plan_for, plan_summary, save_plan, wants_program
    from snakebot.model.plan.program import ProgramPlan
    from snakebot.model.robots import load_robot

    if plot is not None and output is None:
        raise click.UsageError("--plot needs -o FILE: the plot is drawn from the written table")
    as_program = wants_program(output)
    if as_program and plot is not None:
        raise click.UsageError(
            "--plot draws a gait table: for a program, use "
            "`snakebot sim predict FILE.prog --plot PNG`"
        )
    if world != "kinematic" and as_program:
        raise click.UsageError(
            f"--world {world} plans a gait table: write it to a .gait file, not a program"
        )
    if capacity is not None and port is not None:
        raise click.UsageError(
            "--capacity and --port both set the capacity planned for: give one of them"
        )
    chosen = load_robot(robot)
    if port is not None:
        from snakebot.link.controller.upload import table_capacity

        with ControllerLink(port, controller_id=controller_id).open() as ctl:
            capacity = table_capacity(ctl)
    try:
        capacity = DEFAULT_CAPACITY if capacity is None else capacity
        request = PlanRequest(chosen, goal.target, capacity=capacity, **goal.settings())
        if world == "kinematic":
            plan = plan_for(output, request)
        elif world == "both":
            from snakebot.workflows.plan_both import plan_in_both

            plan = plan_in_both(request)
        else:
            from snakebot.workflows.plan_mujoco import plan_in_mujoco

            plan = plan_in_mujoco(request)
    except Unreachable as exc:
        unreachable(exc)
        return
    checks = None
    if world == "both":
        from snakebot.workflows.plan_both import both_check

        checks = both_check(plan)
    elif world != "kinematic":
        from snakebot.workflows.plan_mujoco import world_check

        checks = world_check(plan)
    elif isinstance(plan, (Plan, ProgramPlan)):
        from snakebot.workflows.plan_check import servo_check

        checks = servo_check(plan)
    if output is None:
        summary, table = plan_summary(plan, checks), None
    else:
        summary, table = save_plan(plan, output, checks)
    if table is not None and plot is not None:
        from snakebot.plots.gait import plot_gait

        summary["plot"] = str(plot_gait(table, plot))
    for warning in summary["warnings"]:
        click.echo(f"warning: {warning['message']}", err=True)
    if as_json:
        click.echo(dumps(summary, indent=2))
    elif as_program:
        _print_program(summary)
    elif "cycles" in summary:
        _print_cycles(summary)
    else:
        _print(summary)


def _print_program(s: dict[str, Any]) -> None:
    kinds = ", ".join(
        f"{seg['kind']} ({seg['steps']} step{'' if seg['steps'] == 1 else 's'})"
        for seg in s["segments"]
    )
    hubs = "; ".join(", ".join(f"{math.degrees(v):.1f}" for v in h) for h in s["hubs_rad"])
    click.echo(
        f"program for {s['robot']}: {s['loops']} {s['loop_kind']} loops through "
        f"hub(s) ({hubs}) deg, {s['program_bytes']} bytes of the {s['capacity_bytes']} "
        "planned for, a step every "
        f"{s['step_period_ms']} ms ({s['duration_s']:.2f} s): {kinds}"
    )
    _print_pose(s, "the program's goals as the controller rounds them")
    _print_servo_check(s)
    click.echo(f"wrote {s['file']}")


def _print_cycles(s: dict[str, Any]) -> None:
    click.echo(
        f"plan for {s['robot']} in the {s['world']} world: {s['cycles']} serpenoid cycles "
        f"(lag {math.degrees(s['delta_rad']):.1f} deg between joints), {s['frames']} frames "
        f"every {s['frame_period_ms']} ms ({s['duration_s']:.2f} s), {s['table_bytes']} bytes "
        f"of the {s['capacity_bytes']} planned for; {s['plays']} plays in "
        f"{'MuJoCo' if s['world'] == 'both' else s['world']}"
    )
    both = "mujoco" in s
    _print_pose(
        s, f"the table played open loop in {'the quasi-static world' if both else s['world']}"
    )
    _print_check("in the quasi-static world", s["quasi_static"]["error"], s["length_unit"])
    if both:
        _print_check(
            f"in MuJoCo (bound: {s['mujoco']['bound']:g}x the tolerance)",
            s["mujoco"]["error"],
            s["length_unit"],
        )
    _print_written(s)


def _print_check(how: str, e: dict[str, Any], unit: str) -> None:
    """One line: where the table ends played ``how``, beside the tolerance."""
    verdict = "within the tolerance" if e["within"] else "OUTSIDE the tolerance"
    click.echo(
        f"  {how}: error {e['position']:.4g} {unit}, heading "
        f"{math.degrees(e['heading_rad']):.3f} deg ({verdict})"
    )


def _print_written(s: dict[str, Any]) -> None:
    if "file" in s:
        click.echo(f"wrote {s['file']} and {s['metadata_file']}")
    if "plot" in s:
        click.echo(f"plot written to {s['plot']}")


def _print_pose(s: dict[str, Any], how: str) -> None:
    t, f, e = s["target"], s["predicted_final"], s["error"]
    u = s["length_unit"]
    click.echo(
        f"  target     x = {t['x']: .4f} {u}  y = {t['y']: .4f} {u}  theta = "
        f"{math.degrees(t['theta']): .2f} deg"
    )
    click.echo(
        f"  predicted  x = {f['x']: .4f} {u}  y = {f['y']: .4f} {u}  theta = "
        f"{math.degrees(f['theta']): .2f} deg ({how})"
    )
    click.echo(
        f"  error {e['position']:.4g} {u} (tolerance {e['position_tolerance']:.4g} {u}), heading "
        f"{math.degrees(e['heading_rad']):.3f} deg (tolerance "
        f"{math.degrees(e['heading_tolerance_rad']):.2f} deg)"
    )
    if s["length_legend"]:
        click.echo(f"  ({s['length_legend']})")


def _print(s: dict[str, Any]) -> None:
    click.echo(
        f"plan for {s['robot']}: {s['loops']} loops through hub "
        f"({', '.join(f'{math.degrees(v):.1f}' for v in s['hub_rad'])}) deg, "
        f"{s['frames']} frames every {s['frame_period_ms']} ms ({s['duration_s']:.2f} s), "
        f"{s['table_bytes']} bytes of the {s['capacity_bytes']} planned for"
    )
    _print_pose(s, "the table as the controller plays it")
    unit = s["length_unit"]
    for row in s.get("friction_sensitivity", ()):
        _print_check(f"with {row['rolling_factor']:g}x the rolling resistance", row["error"], unit)
    _print_servo_check(s)
    _print_written(s)


def _print_servo_check(s: dict[str, Any]) -> None:
    check = s.get("servo_check")
    if check is not None:
        label = f"on the modelled servos ({check['servos']})"
        _print_check(label, check["error"], s["length_unit"])
