"""`snakebot sim view` (issue #33): MuJoCo's real viewer in a window of a real X server
(Xvfb, Mesa's GL), its screenshot against the offscreen renderer's picture of the same
state; the command on a gait and on a controller; no display, exit 2."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable

import numpy as np
import pytest
from click.testing import CliRunner
from controller_cli_support import save, wave_table
from PIL import ImageGrab
from test_video3d import SNAKE5, orange, wave
from xvfb_support import display, xvfb

from snakebot.cli import main
from snakebot.plots import render3d, viewer
from snakebot.plots.motion import StateMotion
from snakebot.sim.controller_pty import ControllerPty

pytest.importorskip("mujoco")
pytestmark = pytest.mark.serial  # a window drawn by its own thread, runs shown in real time
__all__ = ["display", "xvfb"]  # the X server the viewer draws on (fixtures)


def red(frame: np.ndarray) -> np.ndarray:
    """Where a path is drawn: its red."""
    r, g, b = (frame[:, :, i].astype(int) for i in range(3))
    return (r > 150) & (g < 90) & (b < 90)


def box(frame: np.ndarray) -> np.ndarray:
    """Where the overlay's text boxes are: the most common flat grey of the frame's
    corners' first column."""
    edge = np.concatenate([frame[:40, 2], frame[-40:, 2]]).astype(int)
    grey = np.bincount(edge[:, 0]).argmax()
    return np.all(frame.astype(int) == grey, axis=2)


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max(1, (a | b).sum()))


def screenshot(window: viewer.LiveView, display: str) -> np.ndarray:
    """The viewer's picture once it holds still (no window manager: its window is at the
    top left). The viewer draws on its own thread: on a busy machine it may be behind."""
    port = window.handle.viewport
    before = None
    deadline = time.monotonic() + 20
    while True:
        shot = np.asarray(ImageGrab.grab(xdisplay=display).convert("RGB"))
        shot = shot[: port.height, : port.width]
        if before is not None and np.array_equal(shot, before):
            return shot
        assert time.monotonic() < deadline, "the viewer's picture never held still"
        before = shot
        time.sleep(0.3)


def assert_same_picture(seen: np.ndarray, drawn: np.ndarray) -> None:
    """The viewer's ``seen`` shows what the offscreen renderer ``drawn``: the robot,
    its path and the overlay's boxes in the same places."""
    body_seen, body_drawn = orange(seen), orange(drawn)
    assert body_drawn.sum() > 2000  # the robot fills part of the picture
    assert iou(body_seen, body_drawn) > 0.9  # same pose, same camera, same place
    rows, cols = np.nonzero(body_seen)
    rows_drawn, cols_drawn = np.nonzero(body_drawn)
    assert abs(rows.mean() - rows_drawn.mean()) < 2 and abs(cols.mean() - cols_drawn.mean()) < 2
    # the path where the offscreen picture draws it (the viewer's lines are a pixel
    # wider: within a pixel)
    path_seen, path_drawn = red(seen), red(drawn)
    near = np.zeros_like(path_seen)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near |= np.roll(np.roll(path_seen, dy, axis=0), dx, axis=1)
    assert (near & path_drawn).sum() >= 0.9 * path_drawn.sum()
    # the same overlay boxes in the same corners (a flat grey behind the text)
    assert iou(box(seen), box(drawn)) > 0.7
    # and the same light: the same colours (window and offscreen buffer differ in
    # antialiasing and line width, at edges only)
    diff = np.abs(seen.astype(int) - drawn.astype(int)).max(axis=2)
    assert diff.mean() < 3 and (diff > 40).mean() < 0.03  # measured: 1.3, 0.012-0.013


def settle(show: Callable[[], bool]) -> None:
    """Show a state a few times: the viewer draws on its own thread."""
    for _ in range(10):
        assert show()
        time.sleep(0.1)


def test_the_viewer_shows_the_state_the_offscreen_renderer_draws(display):
    run = wave(2.0)
    with viewer.LiveView(SNAKE5) as window:
        posed = render3d.Posed(window.mj, window.model, SNAKE5, run)
        settle(lambda: window.show_posed(posed, 1.0, "wave"))
        seen = screenshot(window, display)
    with render3d.Renderer3D(SNAKE5, (seen.shape[1], seen.shape[0])) as renderer:
        drawn = renderer.frame({"wave": run}, 1.0)
    assert red(drawn).sum() > 20  # a path to compare
    assert_same_picture(seen, drawn)


def test_mirror_puts_the_model_at_the_angles_it_is_given(display):
    angles = np.radians([40.0, -20.0, 30.0, -45.0])
    pose = np.array([0.3, -0.1, 0.5])
    still = StateMotion(np.zeros(1), pose[None], angles[None])
    with viewer.LiveView(SNAKE5) as window:
        settle(lambda: viewer.mirror(window, [(0.0, angles)], "still", lambda t, a: pose) == 1)
        seen = screenshot(window, display)
    with render3d.Renderer3D(SNAKE5, (seen.shape[1], seen.shape[0])) as renderer:
        drawn = renderer.frame({"still": still}, 0.0)
    assert_same_picture(seen, drawn)


def test_sim_view_plays_a_gait_once_and_closes(display, tmp_path):
    gait = save(wave_table(frames=50), tmp_path)  # 50 frames of 20 ms: a 1 s run
    started = time.monotonic()
    result = CliRunner().invoke(main, ["sim", "view", str(gait), "--robot", "snake5", "--once"])
    assert result.exit_code == 0, result.output
    assert "viewer is open" in result.stderr
    assert time.monotonic() - started >= 1.0  # shown at the run's own pace


VIEWER_MARGIN_MS = "2000"
"""The reply margin of `sim view --port` on the in-process emulated controller: the viewer
opens its window in the same process, and in a fresh clone's CI run (the serial stage
beside three other lanes) the controller's first READ went unanswered through three tries
of 200 ms while it did. The test counts looks, not how fast they come."""


def test_sim_view_mirrors_a_controllers_joint_angles(display, tmp_path):
    with ControllerPty(robot="snake5", table=wave_table().encode()) as controller:
        result = CliRunner().invoke(
            main,
            ["sim", "view", "--port", controller.device, "--robot", "snake5"]
            + ["--duration", "0.3", "--interval", "0.1"],
            env={"SNAKEBOT_MARGIN_MS": VIEWER_MARGIN_MS},
        )
        assert controller.error is None, controller.error
    assert result.exit_code == 0, result.output
    assert "showed 4 looks at the controller" in result.stderr  # at 0, 0.1, 0.2, 0.3 s


def test_without_a_display_it_exits_2_naming_the_fix(tmp_path, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    gait = save(wave_table(), tmp_path)
    result = CliRunner().invoke(main, ["sim", "view", str(gait), "--robot", "snake5"])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "set DISPLAY" in lines[0] and "--video" in lines[0]


@pytest.mark.parametrize(
    "args, words",
    [
        ([], "either GAIT"),
        (["--port", "/dev/ttyUSB0"], "--port needs --robot"),
    ],
)
def test_what_to_show_is_checked_before_anything_opens(args, words):
    result = CliRunner().invoke(main, ["sim", "view", *args])
    assert result.exit_code == 2 and words in result.stderr


def test_the_command_ends_cleanly_as_a_process(display, tmp_path):
    """The process ends after the viewer's window is gone (it once ended while the
    viewer's thread still tore the window down: a segmentation fault at exit)."""
    gait = save(wave_table(frames=25), tmp_path)
    command = [sys.executable, "-m", "snakebot", "sim", "view", str(gait), "--robot", "snake5"]
    done = subprocess.run(
        [*command, "--once"], capture_output=True, text=True, timeout=60, env=os.environ
    )
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "Segmentation" not in done.stderr
