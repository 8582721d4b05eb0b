"""The robot in 3-D, drawn by MuJoCo's own renderer offscreen (EGL, or OSMesa where EGL is
missing: no display, no GPU needed).

The model is the physics world's (:func:`snakebot.sim.physics.mjcf.build_mjcf`): its
links, wheels and floor, here with grid lines on the floor every metre (darker) and half metre.
A run is shown by putting the model in each recorded state (the body's pose and the
joint angles; the wheels turn by the distance they rolled), so a kinematic prediction is
drawn as well as a physics run. The first run is drawn in the robot's colours; each
other run beside it is a translucent copy in its own colour. Each run's path is drawn on
the floor as it goes; the camera follows the first run's body from behind and above,
its heading fixed (the floor does not spin); the overlay gives the time and the first
run's joint angles.

    with Renderer3D(robot, (1280, 720)) as r:
        frame = r.frame({"emulated": record}, t=1.0)   # (720, 1280, 3) uint8
"""

from __future__ import annotations

import importlib
import math
import os
from collections.abc import Mapping, Sequence
from types import TracebackType
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

from snakebot.errors import RuntimeFailure
from snakebot.extras import available
from snakebot.model.robots import Robot
from snakebot.plots.motion import Motion, sample_index
from snakebot.sim.physics.mjcf import build_mjcf, physics_of

BACKENDS = ("egl", "osmesa")
"""MuJoCo's offscreen GL backends, in the order tried; MUJOCO_GL names one to use alone."""

TINTS = ((0.2, 0.4, 0.9, 0.45), (0.2, 0.7, 0.3, 0.45))
"""Colours of the second, third, ... run's robot (RGBA)."""

PATH_COLOURS = ((0.85, 0.1, 0.1, 1.0), (0.2, 0.4, 0.9, 1.0), (0.2, 0.7, 0.3, 1.0))
LEGEND = ("its own colours, red path", "blue, blue path", "green, green path")
"""How the overlay names each run's colours (in the order of TINTS and PATH_COLOURS)."""
TINY_HEIGHT, SMALL_HEIGHT = 200, 300
"""Below these heights the overlay gives nothing, or only the time."""
PATH_SEGMENTS = 100
"""At most this many segments draw a path (longer paths are thinned)."""
LINE_Z = 0.001
"""Lines on the floor are drawn this far above it (metres), so the floor does not hide them."""
PATH_WIDTH_PX = 360
"""A path is one pixel wide per this many pixels of the picture's height (at least one)."""

FLOOR_RGBA = "0.9 0.9 0.9 1"
GRID_COLOURS = ((0.35, 0.35, 0.35, 1.0), (0.7, 0.7, 0.7, 1.0))
"""The floor's lines every metre, and between them every half metre."""
GRID_REACH = 4.0
"""Grid lines reach this many camera distances from the point the camera looks at (about
as far as the floor shows; beyond, the floor is plain)."""


class RendererUnavailable(RuntimeFailure):
    """MuJoCo's offscreen renderer cannot start here (no EGL or OSMesa, or no MuJoCo)."""


def can_render(robot: Robot) -> bool:
    """Whether ``robot`` can be drawn in 3-D: MuJoCo is installed and the robot has a
    ``[physics]`` table (the GL backend is only known once a context is made)."""
    return available("mujoco") and robot.physics is not None


def font_scale(height: int) -> Any:
    """The overlay's font for a picture ``height`` pixels high (readable, not crowding)."""
    import mujoco

    scales = mujoco.mjtFontScale
    if height <= 240:
        return scales.mjFONTSCALE_50
    return scales.mjFONTSCALE_100 if height <= 600 else scales.mjFONTSCALE_150


def _context(width: int, height: int) -> tuple[str, Any]:
    """An offscreen GL context made current, and its backend's name."""
    wanted = os.environ.get("MUJOCO_GL", "").lower()
    failures = []
    for name in (wanted,) if wanted in BACKENDS else BACKENDS:
        try:
            context = importlib.import_module(f"mujoco.{name}").GLContext(width, height)
            context.make_current()
            return name, context
        except Exception as exc:  # each backend fails in its own way (ImportError, GL errors)
            failures.append(f"{name}: {exc}".strip())
    raise RendererUnavailable(
        "MuJoCo's offscreen renderer could not start (" + "; ".join(failures) + "): install "
        "EGL or OSMesa (apt-get install libegl1 libgl1-mesa-dri libosmesa6; `make setup` "
        "does), or set MUJOCO_GL=egl or osmesa"
    )


def render_model_xml(robot: Robot) -> str:
    """The physics world's MJCF of ``robot`` with a plain floor (the renderer draws its
    metre grid as lines: on a software rasteriser a textured floor costs more than the
    rest of the picture)."""
    root = ET.fromstring(build_mjcf(robot)[0])
    for geom in root.iter("geom"):
        if geom.get("name") == "floor":
            geom.set("rgba", FLOOR_RGBA)
    for quality in root.iter("visual"):
        ET.SubElement(quality, "quality", shadowsize="0", offsamples="0")
        ET.SubElement(quality, "headlight", ambient="0.3 0.3 0.3", diffuse="0.15 0.15 0.15")
    for light in root.iter("light"):  # with the headlight: a floor in light grey, not white
        light.set("diffuse", "0.5 0.5 0.5")
    return ET.tostring(root, encoding="unicode")


class Posed:
    """One run put into a MuJoCo state at any time: root pose, joints and wheel spin."""

    def __init__(self, mujoco: Any, model: Any, robot: Robot, motion: Motion) -> None:
        self.mj, self.model, self.motion = mujoco, model, motion
        self.data = mujoco.MjData(model)
        self.unit = physics_of(robot).unit_m
        self.radius = physics_of(robot).wheel_radius_m
        joints = [model.joint(j.name) for j in robot.joints]
        self.qadr = np.array([int(j.qposadr[0]) for j in joints])
        wheels = [model.joint(f"wheel{k + 1}") for k in range(robot.n_wheels)]
        self.wheel_qadr = np.array([int(w.qposadr[0]) for w in wheels])
        self.wheel_body = np.array([int(w.bodyid[0]) for w in wheels])
        self.spin, self.centre = self._rolled()

    def _place(self, k: int) -> None:
        q = self.data.qpos
        x, y, theta = (float(v) for v in self.motion.pose[k])
        q[0], q[1], q[2], q[3] = x * self.unit, y * self.unit, 0.0, theta
        q[self.qadr] = self.motion.phi[k]

    def _rolled(self) -> tuple[np.ndarray, np.ndarray]:
        """Each wheel's turn at every sample (the distance its centre rolled along its
        heading, over its radius), and the body's centre (the wheels' mean, metres)."""
        n = len(self.motion.t)
        spin = np.zeros((n, len(self.wheel_qadr)))
        middle = np.zeros((n, 2))
        last = None
        for k in range(n):
            self._place(k)
            self.mj.mj_kinematics(self.model, self.data)
            centre = self.data.xpos[self.wheel_body, :2].copy()
            ahead = self.data.xmat[self.wheel_body].reshape(-1, 3, 3)[:, :2, 0]
            if last is not None:
                spin[k] = spin[k - 1] + np.sum((centre - last) * ahead, axis=1) / self.radius
            last = centre
            middle[k] = centre.mean(axis=0)
        return spin, middle

    def at(self, t: float) -> int:
        """Put the run in its state at time ``t`` (the sample at or before it); its index."""
        k = sample_index(self.motion.t, t)
        self._place(k)
        self.data.qpos[self.wheel_qadr] = self.spin[k]
        self.mj.mj_kinematics(self.model, self.data)
        self.mj.mj_camlight(self.model, self.data)  # the lights' places: unlit without
        return k

    def path(self, k: int) -> np.ndarray:
        """The body centre's path up to sample ``k`` (metres), thinned to PATH_SEGMENTS."""
        xy = self.centre[: k + 1]
        if len(xy) > PATH_SEGMENTS + 1:
            xy = xy[np.linspace(0, len(xy) - 1, PATH_SEGMENTS + 1).round().astype(int)]
        return xy


def aim(camera: Any, robot: Robot) -> None:
    """Make ``camera`` (an MjvCamera) look at ``robot`` from behind and above, at a
    distance that shows its whole body; its ``lookat`` is the caller's to move."""
    import mujoco

    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.azimuth, camera.elevation = -140.0, -30.0
    snake = robot.kind == "snake"
    size_m = 2 * robot.l * robot.links if snake else 2 * (robot.r + robot.l)
    camera.distance = max(0.5, 1.6 * size_m * physics_of(robot).unit_m)


class FloorLines:
    """Lines on the floor added to a MuJoCo scene (an MjvScene: the renderer's, or a
    viewer's user scene): the metre grid and the runs' paths, as wide as a picture
    ``height`` pixels high wants. Lines, not capsules: a capsule is hundreds of
    triangles, and a path of them costs a software rasteriser more than the robot and
    the floor together."""

    def __init__(self, mujoco: Any, scene: Any, height: int) -> None:
        self.mj, self.scene = mujoco, scene
        self.width_px = max(1, round(height / PATH_WIDTH_PX))
        self._zeros, self._eye = np.zeros(3), np.eye(3).ravel()
        self._grid_rgba = [np.asarray(c, dtype=np.float32) for c in GRID_COLOURS]

    def line(self, a: Sequence[float], b: Sequence[float], rgba: np.ndarray) -> bool:
        """Add a line from ``a`` to ``b`` (x, y in metres); False when the scene is full."""
        mj, scene = self.mj, self.scene
        if scene.ngeom >= scene.maxgeom:
            return False
        geom = scene.geoms[scene.ngeom]
        mj.mjv_initGeom(geom, mj.mjtGeom.mjGEOM_LINE, self._zeros, self._zeros, self._eye, rgba)
        ends = (np.array([a[0], a[1], LINE_Z], float), np.array([b[0], b[1], LINE_Z], float))
        mj.mjv_connector(geom, mj.mjtGeom.mjGEOM_LINE, float(self.width_px), *ends)
        scene.ngeom += 1
        return True

    def grid(self, camera: Any) -> None:
        """The floor's grid around the point ``camera`` looks at, fixed to the floor."""
        reach = GRID_REACH * camera.distance
        x0, y0 = (float(v) for v in camera.lookat[:2])
        for step, colour in zip((1.0, 0.5), self._grid_rgba, strict=True):
            for axis, (c0, c1) in enumerate(((x0, y0), (y0, x0))):
                for c in np.arange(math.ceil((c0 - reach) / step), (c0 + reach) / step) * step:
                    if step < 1.0 and c % 1.0 == 0.0:
                        continue  # a metre line is drawn already
                    ends = ((c, c1 - reach), (c, c1 + reach))
                    a, b = ends if axis == 0 else (e[::-1] for e in ends)
                    if not self.line(a, b, colour):
                        return

    def path(self, xy: np.ndarray, rgba: Sequence[float]) -> None:
        """The path through the points ``xy`` (metres)."""
        moved = np.any(xy[1:] != xy[:-1], axis=1)
        colour = np.asarray(rgba, dtype=np.float32)
        for a, b in zip(xy[:-1][moved].tolist(), xy[1:][moved].tolist(), strict=True):
            if not self.line(a, b, colour):
                return


def overlay_texts(
    mujoco: Any, robot: Robot, labels: Sequence[str], t: float, phi: Sequence[float], height: int
) -> list[tuple[Any, str, str]]:
    """The overlay of a picture ``height`` pixels high at time ``t``, the first run's
    joints at ``phi`` (rad): (corner, left column, right column) per text box."""
    if height < TINY_HEIGHT:
        return []  # a thumbnail: any text would cover the robot
    grid = mujoco.mjtGridPos
    texts = [(grid.mjGRID_TOPLEFT, "time\nfloor", f"{t:.2f} s\n1 m grid")]
    if height < SMALL_HEIGHT:
        return texts  # small: the angles and the legend would cover the robot
    angles = "\n".join(
        f"{j.name} {math.degrees(a):+6.1f} deg" for j, a in zip(robot.joints, phi, strict=True)
    )
    legend = "\n".join(f"{label}: {colour}" for label, colour in zip(labels, LEGEND, strict=False))
    texts.append((grid.mjGRID_BOTTOMLEFT, angles, ""))
    texts.append((grid.mjGRID_BOTTOMRIGHT, legend, ""))
    return texts


class Renderer3D:
    """Frames of runs of ``robot``, ``size`` = (width, height) pixels."""

    def __init__(self, robot: Robot, size: tuple[int, int]) -> None:
        if not can_render(robot):
            raise RendererUnavailable(
                f"{robot.name} cannot be drawn in 3-D: it needs MuJoCo and a [physics] table"
            )
        import mujoco

        self.mj, self.robot = mujoco, robot
        self.width, self.height = size
        self.backend, self._gl = _context(self.width, self.height)
        model = mujoco.MjModel.from_xml_string(render_model_xml(robot))
        model.vis.global_.offwidth, model.vis.global_.offheight = self.width, self.height
        self.model = model
        self.scene = mujoco.MjvScene(model, maxgeom=2000 + 4 * PATH_SEGMENTS)
        self.option = mujoco.MjvOption()
        for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION):
            self.scene.flags[flag] = False  # software GL: each would double a frame's cost
        self.camera = mujoco.MjvCamera()
        aim(self.camera, robot)
        self.context = mujoco.MjrContext(model, font_scale(self.height))
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self.context)
        self.viewport = mujoco.MjrRect(0, 0, self.width, self.height)
        self._runs: dict[int, Posed] = {}
        self._pixels = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self.lines = FloorLines(mujoco, self.scene, self.height)

    def _posed(self, motion: Motion) -> Posed:
        posed = self._runs.get(id(motion))
        if posed is None or posed.motion is not motion:
            posed = self._runs[id(motion)] = Posed(self.mj, self.model, self.robot, motion)
        return posed

    def frame(self, runs: Mapping[str, Motion], t: float) -> np.ndarray:
        """The picture of ``runs`` (label -> run, the first followed by the camera) at time
        ``t``: (height, width, 3) uint8, top row first."""
        mj, scene = self.mj, self.scene
        posed = [self._posed(m) for m in runs.values()]
        ks = [p.at(t) for p in posed]
        first = posed[0]
        self.camera.lookat[:] = [*first.centre[ks[0]], 0.0]
        mj.mjv_updateScene(
            self.model, first.data, self.option, None, self.camera, mj.mjtCatBit.mjCAT_ALL, scene
        )
        for i, p in enumerate(posed[1:]):
            before = scene.ngeom
            mj.mjv_addGeoms(
                self.model, p.data, self.option, mj.MjvPerturb(), mj.mjtCatBit.mjCAT_DYNAMIC, scene
            )
            for g in range(before, scene.ngeom):
                scene.geoms[g].rgba[:] = TINTS[i % len(TINTS)]
        self.lines.grid(self.camera)
        for i, (p, k) in enumerate(zip(posed, ks, strict=True)):
            self.lines.path(p.path(k), PATH_COLOURS[i % len(PATH_COLOURS)])
        mj.mjr_render(self.viewport, scene, self.context)
        for place, left, right in overlay_texts(
            mj, self.robot, list(runs), t, first.motion.phi[ks[0]], self.height
        ):
            mj.mjr_overlay(
                mj.mjtFont.mjFONT_NORMAL, place, self.viewport, left, right, self.context
            )
        mj.mjr_readPixels(self._pixels, None, self.viewport, self.context)
        return np.flipud(self._pixels).copy()

    def close(self) -> None:
        if self._gl is not None:
            self.context.free()
            self._gl.free()
            self._gl = None

    def __enter__(self) -> Renderer3D:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
