"""Videos from MuJoCo's offscreen renderer (issue #33): real MuJoCo on EGL or OSMesa, the
ffmpeg that imageio-ffmpeg ships; small pictures and short runs, but the golden frame."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from snakebot.model.robots import load_robot
from snakebot.plots import render3d, video
from snakebot.plots.motion import StateMotion

pytest.importorskip("mujoco")
imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")

SNAKE5 = load_robot("snake5")
GOLDEN = Path(__file__).parent / "golden" / "snake5-3d.png"
SMALL = (160, 96)


def wave(seconds: float, rate: float = 50.0) -> StateMotion:
    """snake5 going along x while its joints wave: a made-up run, the same every time."""
    t = np.arange(0.0, seconds + 1e-9, 1 / rate)
    phase = 2 * math.pi * t[:, None] - np.arange(4) * math.pi / 2
    phi = math.radians(30) * np.sin(phase)
    pose = np.column_stack([0.2 * t, 0.02 * np.sin(t), 0.1 * t])
    return StateMotion(t, pose, phi)


def orange(frame: np.ndarray) -> np.ndarray:
    """Where the links are: their orange, lit or shaded."""
    r, g, b = (frame[:, :, i].astype(int) for i in range(3))
    return (r > 90) & (r - b > 70) & (g > b)


def frames_of(path: Path) -> list[np.ndarray]:
    if path.suffix == ".gif":
        with Image.open(path) as image:
            out = []
            for k in range(image.n_frames):
                image.seek(k)
                out.append(np.asarray(image.convert("RGB")))
            return out
    reader = imageio_ffmpeg.read_frames(str(path))
    width, height = next(reader)["size"]
    return [np.frombuffer(f, np.uint8).reshape(height, width, 3) for f in reader]


@pytest.mark.parametrize("suffix", [".gif", ".mp4"])
def test_a_video_has_its_frames_size_and_a_moving_robot(tmp_path, suffix):
    notes = []
    path = video.write_video(
        tmp_path / f"run{suffix}", SNAKE5, {"wave": wave(0.5)}, size=SMALL, say=notes.append
    )
    assert notes == []  # drawn in 3-D, no fallback
    frames = frames_of(path)
    assert len(frames) == int(0.5 * video.frame_rate(path)) + 1
    assert all(f.shape == (SMALL[1], SMALL[0], 3) for f in frames)
    first, last = orange(frames[0]), orange(frames[-1])
    assert first.sum() > 50 and last.sum() > 50  # the robot is in the picture
    overlap = (first & last).sum() / (first | last).sum()
    assert overlap < 0.8  # ... and it moved: its links are elsewhere on the screen
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temp file left


def test_one_frame_matches_the_golden_image():
    with render3d.Renderer3D(SNAKE5, (640, 360)) as renderer:
        frame = renderer.frame({"wave": wave(2.0)}, 1.0)
    if not GOLDEN.exists():  # pragma: no cover - writes the golden image the first time
        Image.fromarray(frame).save(GOLDEN)
        pytest.skip(f"wrote {GOLDEN}: check it by eye and commit it")
    golden = np.asarray(Image.open(GOLDEN).convert("RGB")).astype(int)
    diff = np.abs(frame.astype(int) - golden)
    # the same GL stack draws the same pixels; another rasteriser shifts edges a little
    assert diff.mean() < 3.0
    assert (diff.max(axis=2) > 40).mean() < 0.01


def test_without_a_renderer_the_video_is_drawn_from_above(tmp_path, monkeypatch):
    def unavailable(width, height):
        raise render3d.RendererUnavailable("no EGL here")

    monkeypatch.setattr(render3d, "_context", unavailable)
    notes = []
    path = video.write_video(
        tmp_path / "run.gif", SNAKE5, {"wave": wave(0.3)}, size=(320, 240), say=notes.append
    )
    assert len(notes) == 1 and "2-D" in notes[0] and "no EGL here" in notes[0]
    assert len(frames_of(path)) == int(0.3 * video.GIF_FPS) + 1


@pytest.mark.parametrize("text", ["1280", "1280x721", "10x10", "axb", "8000x720"])
def test_bad_sizes_are_refused(text):
    with pytest.raises(video.VideoError, match="WIDTHxHEIGHT|even number"):
        video.parse_size(text)
