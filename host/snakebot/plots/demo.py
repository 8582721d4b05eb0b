"""The demo's pictures: the body's paths and the joint angles (``demo.png``), and the video
of the emulated robot when asked for."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from snakebot.extras import available
from snakebot.model.robots import Robot, load_robot
from snakebot.plots.joints import draw_joints
from snakebot.plots.video import write_video
from snakebot.workflows.demo import Comparison, DemoResult, Say, _why


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
        write_video(settings.video, robot, {f"emulated ({settings.world})": result.record})
    return replace(result, png=png)


def plot_demo(robot: Robot, comparison: Comparison, out: Path) -> Path:
    """PNG: the body's path (emulated, predicted) and the joint angles (commanded, measured)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(13, 5), layout="constrained")
    FigureCanvasAgg(fig)
    ax_path, ax_joints = fig.subplots(1, 2, width_ratios=(1, 1.4))
    em, pr = comparison.emulated_path, comparison.predicted_path
    ax_path.plot(pr[:, 0], pr[:, 1], "--", color="tab:blue", label="predicted (table)")
    ax_path.plot(em[:, 0], em[:, 1], "-", color="tab:red", label="emulated (firmware in QEMU)")
    ax_path.plot([0], [0], "o", color="black", label="start")
    ax_path.set_aspect("equal", adjustable="datalim")
    ax_path.set_xlabel("x (m, along link 1 from the tail towards the head, at the start)")
    ax_path.set_ylabel("y (m)")
    ax_path.set_title(
        f"{robot.name}: body path over the measured cycles\n"
        f"difference {100 * comparison.difference_m:.1f} cm\n{_why(comparison)}"
    )
    ax_path.legend(fontsize="small")
    ax_path.grid(alpha=0.3)
    draw_joints(ax_joints, None, comparison.joints, "measured", "commanded", comparison.window_s[0])
    ax_joints.set_xlabel("time since the measured cycles began (s)")
    fig.savefig(out, dpi=100)
    return out
