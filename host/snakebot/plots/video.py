"""Videos of runs: the robot in 3-D from MuJoCo's offscreen renderer
(:mod:`snakebot.plots.render3d`), or, where that cannot start (no EGL or OSMesa, no
MuJoCo, a robot without a ``[physics]`` table), the matplotlib view from above
(:mod:`snakebot.plots.topview`), said on stderr. Both are encoded by the ffmpeg that the
``imageio-ffmpeg`` package ships (no ffmpeg on PATH needed): MP4 (H.264) or GIF.

    write_video("run.mp4", robot, {"kinematic": rec_a, "mujoco": rec_b}, size=(1280, 720))
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Mapping
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from snakebot.errors import InputError, quoted
from snakebot.extras import require
from snakebot.model.robots import Robot
from snakebot.plots.motion import Motion, StateMotion
from snakebot.userfiles import staged_output

__all__ = ["StateMotion", "check_video_path", "parse_size", "write_video"]

FPS = 20
GIF_FPS = 10
"""A GIF's frames a second: each of its frames gets its own palette, dear to make, and a GIF
is a preview (an MP4 has FPS)."""
MAX_FRAMES = 300
"""Longer runs are shown faster (the overlay's clock is the run's time)."""

DEFAULT_SIZE = (1280, 720)
MIN_SIDE, MAX_SIDE = 64, 3840
SUFFIXES = (".mp4", ".gif")


class VideoError(InputError):
    """A video that cannot be written as asked."""


def parse_size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in pixels, each even (H.264 needs it) and within the limits."""
    parts = text.lower().split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise VideoError(
            f"{quoted(text)} is not a size: give WIDTHxHEIGHT, e.g. 1280x720"
        ) from None
    for side in (width, height):
        if not MIN_SIDE <= side <= MAX_SIDE or side % 2:
            raise VideoError(
                f"{quoted(text)}: each side must be an even number of pixels from {MIN_SIDE} to "
                f"{MAX_SIDE}, e.g. 1280x720"
            )
    return width, height


def check_video_path(path: Path) -> Path:
    """``path`` if a video can be written there (raises VideoError otherwise), before any
    long run starts."""
    if path.suffix.lower() not in SUFFIXES:
        raise VideoError(f"{path}: the video must be a .gif or an .mp4 file")
    if not path.parent.is_dir():
        raise VideoError(f"{path}: the directory {path.parent} does not exist")
    require("imageio_ffmpeg", "writing a video", params=("video",))
    return path


def frame_rate(path: Path) -> int:
    """The frames a second of a video written to ``path``: GIF_FPS for a GIF, else FPS."""
    return GIF_FPS if path.suffix.lower() == ".gif" else FPS


def frame_times(runs: Mapping[str, Motion], fps: int = FPS) -> np.ndarray:
    """The times the frames show: ``fps`` a second of the first run, MAX_FRAMES at most."""
    items = list(runs.values())
    if not items or not len(items[0].t):
        raise VideoError("nothing to show: the run recorded no samples")
    duration = float(items[0].t[-1])
    frames = max(2, min(MAX_FRAMES, int(duration * fps) + 1))
    return np.linspace(0.0, duration, frames)


def _encoder(path: Path, size: tuple[int, int], fps: int) -> Generator[None, np.ndarray, None]:
    """imageio-ffmpeg's frame writer for ``path`` (primed): send it (h, w, 3) uint8. It is
    a child process, encoding while the next frame is drawn."""
    import imageio_ffmpeg

    if path.suffix.lower() == ".gif":
        # a palette per frame from that frame's colours, kept as the frames stream by
        options: dict[str, Any] = {
            "codec": "gif",
            "pix_fmt_out": "pal8",
            "output_params": [
                "-filter_complex",
                "split[a][b];[a]palettegen=stats_mode=single[p];[b][p]paletteuse=new=1",
                "-loop",
                "0",
            ],
        }
    else:
        # x264's fastest preset: a quarter of the CPU of its default on these pictures
        # (which cost more than drawing them), at x264's default quality, a larger file
        options = {
            "codec": "libx264",
            "quality": None,
            "pix_fmt_out": "yuv420p",
            "output_params": ["-preset", "ultrafast", "-crf", "23"],
        }
    writer = imageio_ffmpeg.write_frames(
        str(path), size, fps=fps, macro_block_size=1, ffmpeg_log_level="error", **options
    )
    writer.send(None)
    return writer


Draw = Callable[[float], np.ndarray]


def open_view(
    robot: Robot,
    runs: Mapping[str, Motion],
    title: str,
    size: tuple[int, int],
    say: Callable[[str], Any],
) -> tuple[Draw, Callable[[], None], str]:
    """The frame function of the 3-D renderer, or of the top view where that cannot
    start; the function that frees it; and which it is (``3d`` or ``2d``)."""
    from snakebot.plots.render3d import Renderer3D, RendererUnavailable

    try:
        renderer = Renderer3D(robot, size)
    except RendererUnavailable as exc:
        say(f"note: drawing the video from above in 2-D instead of in 3-D: {exc}")
        from snakebot.plots.topview import TopView

        view = TopView(robot, runs, title, size)
        return view.frame, view.close, "2d"
    return partial(renderer.frame, runs), renderer.close, "3d"


def write_video(
    path: str | Path,
    robot: Robot,
    records: Mapping[str, Motion],
    title: str = "",
    *,
    size: tuple[int, int] = DEFAULT_SIZE,
    say: Callable[[str], Any] = print,
) -> Path:
    """Write the runs in ``records`` (label -> run, sharing one time axis; the camera
    follows the first) to ``path`` (.mp4 or .gif), ``size`` = (width, height) pixels."""
    path = check_video_path(Path(path))
    fps = frame_rate(path)
    times = frame_times(records, fps)
    draw, close, _ = open_view(robot, records, title, size, say)
    try:
        with staged_output(path) as temp:
            writer = _encoder(temp, size, fps)
            try:
                for t in times:
                    writer.send(np.ascontiguousarray(draw(float(t))))
            finally:
                writer.close()
    finally:
        close()
    return path
