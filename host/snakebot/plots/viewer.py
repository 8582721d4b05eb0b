"""MuJoCo's own viewer on the robot, for a desktop: a window that the mouse turns and
zooms, drawn as the videos are (:mod:`snakebot.plots.render3d`: the physics world's
model, the floor's grid, the path, the time and the joint angles).

Its passive mode: this program puts the model in each state (a run played at its own
pace, or the joint angles a controller reports, the body's pose predicted from them)
and the viewer's thread draws it.

    with LiveView(robot) as view:
        play(view, run, "emulated (mujoco)", once=True)
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from snakebot.errors import InputError, RuntimeFailure
from snakebot.extras import require
from snakebot.model.robots import Robot
from snakebot.plots.motion import Motion, StateMotion
from snakebot.plots.render3d import (
    PATH_COLOURS,
    FloorLines,
    Posed,
    aim,
    overlay_texts,
    render_model_xml,
)

FRAME_S = 1 / 30
"""The viewer is given a new state this often (it draws at its own rate)."""
CLOSE_S = 10.0
"""How long closing waits for the viewer's window to go."""
LINE_HEIGHT = 720
"""Lines on the floor are as wide as in a video this many pixels high."""


class NoDisplay(InputError):
    """No display to open a window on."""


class ViewerUnavailable(RuntimeFailure):
    """MuJoCo's viewer could not open its window."""


def has_display() -> bool:
    """Whether a window can be asked for: an X or Wayland display is named."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class LiveView:
    """MuJoCo's passive viewer on ``robot``; :meth:`show` puts the model in a state."""

    def __init__(self, robot: Robot) -> None:
        require("mujoco", "MuJoCo's viewer")
        if robot.physics is None:
            raise InputError(
                f"{robot.name} has no [physics] table, so MuJoCo cannot show it: add one "
                "(see the built-in robot files)"
            )
        if not has_display():
            raise NoDisplay("no display to open MuJoCo's viewer on: set DISPLAY")
        import mujoco
        import mujoco.viewer

        self.mj, self.robot = mujoco, robot
        self.model = mujoco.MjModel.from_xml_string(render_model_xml(robot))
        self.data = mujoco.MjData(self.model)
        before = set(threading.enumerate())
        try:
            self.handle = mujoco.viewer.launch_passive(
                self.model, self.data, show_left_ui=False, show_right_ui=False
            )
        except Exception as exc:  # GLFW's and GL's errors have no common class
            raise ViewerUnavailable(
                f"MuJoCo's viewer could not open a window on {os.environ.get('DISPLAY')}: "
                f"{exc}; check that the display accepts OpenGL (glxinfo) or film the run"
            ) from None
        # the viewer's thread: closing waits for it, or the process could end while it
        # still tears its window down (a segmentation fault at exit)
        self._threads = set(threading.enumerate()) - before
        with self.handle.lock():
            aim(self.handle.cam, robot)
            flags = self.handle.user_scn.flags  # the viewer takes its scene's flags from here
            flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False  # as the videos: no shadows,
            flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False  # no reflections
        self.lines = FloorLines(mujoco, self.handle.user_scn, LINE_HEIGHT)

    def running(self) -> bool:
        """Whether the window is still open."""
        return bool(self.handle.is_running())

    def show(
        self,
        qpos: np.ndarray,
        centre: Sequence[float],
        path: np.ndarray,
        t: float,
        phi: Sequence[float],
        label: str,
    ) -> bool:
        """Put the model in the state ``qpos``, the camera on ``centre`` (metres), the
        ``path`` drawn so far, the overlay at time ``t`` with the joints at ``phi``;
        False once the window is closed."""
        handle, mj = self.handle, self.mj
        if not handle.is_running():
            return False
        with handle.lock():
            handle.d.qpos[:] = qpos
            mj.mj_kinematics(handle.m, handle.d)
            mj.mj_camlight(handle.m, handle.d)
            handle.cam.lookat[:] = [*centre, 0.0]
            handle.user_scn.ngeom = 0
            self.lines.grid(handle.cam)
            self.lines.path(path, PATH_COLOURS[0])
        height = handle.viewport.height if handle.viewport is not None else LINE_HEIGHT
        font = mj.mjtFont.mjFONT_NORMAL
        texts = overlay_texts(mj, self.robot, [label], t, phi, height)
        handle.set_texts([(font, place, left, right) for place, left, right in texts])
        handle.sync()
        return True

    def show_posed(self, posed: Posed, t: float, label: str) -> bool:
        """:meth:`show` the run ``posed`` at time ``t``."""
        k = posed.at(t)
        return self.show(
            posed.data.qpos, posed.centre[k], posed.path(k), t, posed.motion.phi[k], label
        )

    def close(self) -> None:
        self.handle.close()
        for thread in self._threads:
            thread.join(CLOSE_S)

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def play(
    view: LiveView,
    run: Motion,
    label: str,
    *,
    once: bool,
    clock: Callable[[], float] = time.monotonic,
) -> None:
    """Show ``run`` at its own pace, again and again until the window closes (``once``:
    a single time, then return)."""
    posed = Posed(view.mj, view.model, view.robot, run)
    duration = float(run.t[-1])
    start = clock()
    while True:
        t = clock() - start
        if t > duration:
            if once:
                view.show_posed(posed, duration, label)
                return
            start, t = clock(), 0.0
        if not view.show_posed(posed, t, label):
            return
        time.sleep(max(0.0, FRAME_S - (clock() - start - t)))


def mirror(
    view: LiveView,
    samples: Iterable[tuple[float, Sequence[float]]],
    label: str,
    pose_of: Callable[[float, Sequence[float]], np.ndarray],
) -> int:
    """Show each sample (t seconds, the joint angles in the robot's joint order) as it
    comes, the body at ``pose_of(t, angles)`` (x, y in robot units, theta); the number
    shown. Returns when the samples end or the window closes."""
    centres: list[np.ndarray] = []
    shown = 0
    for t, angles in samples:
        phi = np.asarray(angles, dtype=float)
        pose = np.asarray(pose_of(t, phi), dtype=float)
        posed = Posed(
            view.mj, view.model, view.robot, StateMotion(np.array([t]), pose[None], phi[None])
        )
        posed.at(t)
        centres.append(posed.centre[0])
        if not view.show(posed.data.qpos, centres[-1], np.array(centres), t, phi, label):
            break
        shown += 1
    return shown
