"""The demo's pictures: the body's paths and the joint angles (``demo.png``), and the video
of the emulated robot when asked for."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from snakebot.extras import available
from snakebot.model.robots import Robot, load_robot
from snakebot.plots.files import save_figure
from snakebot.plots.joints import draw_joints
from snakebot.plots.video import DEFAULT_SIZE, write_video
from snakebot.workflows.demo import Comparison, DemoResult, Say, _why

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def draw_demo(result: DemoResult, say: Say = print) -> DemoResult:
    """``result`` with its picture drawn into the demo's folder (the picture needs the
    ``plot`` extra; without it the demo still runs and says so) and its video written when
    the settings ask for one."""
    settings = result.settings
    robot = load_robot(settings.robot)
    png = None
    if available("matplotlib"):
        png = plot_demo(robot, result.comparison, Path(settings.out_dir) / "demo.png")
    if settings.video is not None:
        say(f"   writing the video {settings.video} ...")
        write_video(
            settings.video,
            robot,
            {f"emulated ({settings.world})": result.record},
            size=settings.video_size or DEFAULT_SIZE,
            say=say,
        )
    return replace(result, png=png)


def plot_demo(robot: Robot, comparison: Comparison, out: Path) -> Path:
    """PNG of :func:`demo_figure`."""
    save_figure(demo_figure(robot, comparison), out, 100)
    return out


def demo_figure(robot: Robot, comparison: Comparison) -> Figure:
    """Every path the demo cites (emulated, predicted, and with physics the free-wheel
    prediction), in metres where the robot has a physical size, with the legend below the
    data; and the joint angles (commanded, measured)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13, 5.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax_path, ax_joints = fig.subplots(1, 2, width_ratios=(1, 1.4))
    scale, unit = (robot.physics.unit_m, "m") if robot.physics is not None else (1.0, "u")
    paths = [
        (comparison.predicted_path, "--", "tab:blue", "predicted (table)"),
        (comparison.emulated_path, "-", "tab:red", "emulated (the firmware playing it)"),
    ]
    if comparison.free_wheel_path is not None:
        paths.append(
            (comparison.free_wheel_path, ":", "tab:green", "predicted, free-rolling wheels")
        )
    for path, style, color, label in paths:
        ax_path.plot(scale * path[:, 0], scale * path[:, 1], style, color=color, label=label)
    ax_path.plot([0], [0], "o", color="black", label="start")
    ax_path.set_aspect("equal", adjustable="datalim")
    ax_path.set_xlabel(f"x ({unit}, along link 1 from the tail towards the head, at the start)")
    ax_path.set_ylabel(f"y ({unit}, to the left)")
    ax_path.set_title(
        f"{robot.name}: body path over the measured cycles\n"
        f"difference {100 * comparison.difference_m:.1f} cm\n{_why(comparison)}",
        fontsize="medium",
    )
    # below the axes, never over a path
    ax_path.legend(fontsize="small", loc="upper center", bbox_to_anchor=(0.5, -0.16), ncols=2)
    ax_path.grid(alpha=0.3)
    draw_joints(ax_joints, None, comparison.joints, "measured", "commanded", comparison.window_s[0])
    ax_joints.set_xlabel("time since the measured cycles began (s)")
    ax_joints.legend(fontsize="x-small", loc="upper center", bbox_to_anchor=(0.5, -0.16), ncols=4)
    if robot.length_legend:
        fig.text(0.01, 0.005, robot.length_legend, fontsize="x-small")
    return fig
