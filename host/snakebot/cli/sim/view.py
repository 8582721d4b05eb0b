"""``snakebot sim view``: MuJoCo's viewer on the emulated robot playing a gait, or on
the joint angles a controller reports."""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import click

from snakebot.cli.options import (
    CONTROLLER_PORT,
    ControllerLink,
    look_options,
    port_option,
    robot_option,
)
from snakebot.cli.params import EXISTING_INPUT
from snakebot.errors import InputError
from snakebot.extras import require

if TYPE_CHECKING:
    from snakebot.link.controller.client import ControllerClient
    from snakebot.model.robots.model import Joint


class ViewOptionError(InputError):
    """`sim view` asked for something it cannot show."""


@click.command("view")
@click.argument("gait_file", metavar="GAIT", type=EXISTING_INPUT, required=False)
@port_option(
    CONTROLLER_PORT,
    purpose="Instead of GAIT: show the joint angles the controller on this port reports",
    required=False,
)
@robot_option(
    "The robot to show",
    otherwise="for GAIT, the one named in its .json; with --port, needed",
)
@click.option(
    "--once",
    is_flag=True,
    help="Play GAIT once and close the window (default: again and again until it is closed).",
)
@look_options(0.05, mode="with --port", until="the window is closed")
def view(
    gait_file: Path | None,
    port: str | None,
    robot: str | None,
    once: bool,
    interval: float,
    duration: float | None,
) -> None:
    """Open MuJoCo's viewer (a window: drag to turn, scroll to zoom) on the robot, drawn
    as --video draws it: the floor's metre grid, the body's path, the time and the joint
    angles; the camera follows the body.

    With GAIT (a .gait or .prog file) the emulated robot plays it in the MuJoCo world
    as `snakebot sim predict --world mujoco` does (computed first, faster than real
    time), then the window shows the run at its own pace. With --port it mirrors a
    controller: the joint angles of each look at its telemetry (as `snakebot monitor`
    reads it), the body's pose predicted from them by the kinematic model.

    It needs a desktop (DISPLAY set); without one, film the run with `snakebot sim
    predict GAIT --world mujoco --video run.mp4`.

    \b
    Example:
      snakebot gait serpenoid snake5 -A 30deg -w 180deg -d 90deg --cycles 1 -o s.gait
      snakebot sim view s.gait --once
      snakebot upload s.gait --port /dev/ttyUSB0
      snakebot play --port /dev/ttyUSB0 --loop
      snakebot sim view --port /dev/ttyUSB0 --robot snake5
    """
    from snakebot.plots.viewer import LiveView, has_display, mirror, play

    if (gait_file is None) == (port is None):
        raise ViewOptionError("give either GAIT (a gait file to play) or --port (a controller)")
    if port is not None and robot is None:
        raise ViewOptionError("--port needs --robot: the robot on the controller, to draw it")
    require("mujoco", "MuJoCo's viewer")
    if not has_display():
        raise ViewOptionError(
            "no display for MuJoCo's viewer: set DISPLAY (a desktop, or xvfb-run), or film "
            "the run with `snakebot sim predict GAIT --world mujoco --video run.mp4`"
        )
    if gait_file is not None:
        from snakebot.workflows.predict import predict_file

        result, _ = predict_file(gait_file, robot, world="mujoco")
        with LiveView(result.robot) as window:
            click.echo("the viewer is open: close its window (or Ctrl-C) to end", err=True)
            play(window, result.emulated, "emulated (mujoco)", once=once)
        return
    from snakebot.model.robots import load_robot
    from snakebot.workflows.foxglove import PosePredictor

    assert robot is not None and port is not None
    the_robot = load_robot(robot)
    with ControllerLink(port).open() as ctl, LiveView(the_robot) as window:
        ctl.identify()
        click.echo("the viewer is open: close its window (or Ctrl-C) to end", err=True)
        samples = _joint_angles(ctl, the_robot.joints, interval, duration)
        shown = mirror(window, samples, f"controller on {port}", PosePredictor(the_robot).update)
    click.echo(f"showed {shown} looks at the controller", err=True)


def _joint_angles(
    ctl: ControllerClient, joints: Sequence[Joint], interval: float, duration: float | None
) -> Iterator[tuple[float, list[float]]]:
    """Each look at the controller: seconds since the first, and the present angles of
    ``joints`` (the robot's, in its order; matched to the roster by name)."""
    from snakebot.link.controller.monitor import joint_sample, sample

    t0 = time.monotonic()
    taken = 0
    while duration is None or taken <= duration / interval + 1e-9:
        s = sample(ctl, t0)
        joint = joint_sample(s)
        by_name = dict(zip(joint.names, joint.present, strict=True))
        missing = [j.name for j in joints if j.name not in by_name]
        if missing:
            raise ViewOptionError(
                f"the controller's roster has no joint {', '.join(missing)} of the robot: "
                "give the robot it drives as --robot"
            )
        yield s.t, [by_name[j.name] for j in joints]
        taken += 1
        wait = t0 + taken * interval - time.monotonic()
        if wait > 0:
            time.sleep(wait)
