"""Videos of runs seen from above: real matplotlib and Pillow, headless."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner
from physics_support import snake5_serpenoid_file
from PIL import Image

from snakebot.cli import main
from snakebot.model.robots import load_robot
from snakebot.plots.video import FPS, body_points

pytest.importorskip("mujoco")


def test_body_points_follow_the_models_geometry():
    snake = load_robot("snake5")
    chain, wheels = body_points(snake, np.array([1.0, 2.0, 0.0]), np.zeros(4))
    step = 2 * snake.l
    assert np.allclose(chain[:, 0], 1.0 + step * np.arange(6)) and np.allclose(chain[:, 1], 2.0)
    assert np.allclose(wheels[:, 0], 1.0 + step * (np.arange(5) + 0.5))
    # a quarter turn at joint 1 sends link 2 along +y
    chain, _ = body_points(snake, np.zeros(3), np.array([math.pi / 2, 0, 0, 0]))
    assert np.allclose(chain[2], [step, step])
    trident = load_robot("trident")
    _, ends = body_points(trident, np.zeros(3), np.zeros(3))
    radius = trident.r + trident.l
    expected = [[radius * math.cos(a), radius * math.sin(a)] for a in trident.alphas]
    assert np.allclose(ends, expected)


def test_predict_writes_a_gif_of_the_run(tmp_path):
    path = snake5_serpenoid_file(tmp_path)
    gif = tmp_path / "run.gif"
    result = CliRunner().invoke(
        main, ["sim", "predict", str(path), "--world", "mujoco", "--video", str(gif)]
    )
    assert result.exit_code == 0, result.output
    with Image.open(gif) as image:
        assert image.format == "GIF"
        # 2 s at FPS frames a second (Pillow merges frames that do not change)
        assert 2 * FPS - 3 <= image.n_frames <= 2 * FPS + 1
        first = np.asarray(image.convert("RGB"))
        image.seek(image.n_frames - 1)
        last = np.asarray(image.convert("RGB"))
    assert (first != last).any()  # the robot moved


def test_thesis_writes_one_video_per_run(tmp_path):
    video = tmp_path / "thesis.gif"
    result = CliRunner().invoke(
        main,
        [
            "sim",
            "thesis",
            "-o",
            str(tmp_path),
            "--only",
            "g1",
            "--only",
            "g3",
            "--video",
            str(video),
        ],
    )
    assert result.exit_code == 0, result.output
    for name in ("g1", "g3"):
        with Image.open(tmp_path / f"thesis-{name}.gif") as image:
            assert image.n_frames > 10


@pytest.mark.parametrize("name", ["run.avi", "missing/run.gif"])
def test_a_video_that_cannot_be_written_is_refused_before_the_run(tmp_path, name):
    result = CliRunner().invoke(
        main,
        ["sim", "thesis", "-o", str(tmp_path), "--only", "g1", "--video", str(tmp_path / name)],
    )
    assert result.exit_code == 2
    assert result.output.startswith("error: ") and result.output.count("\n") == 1
    assert not (tmp_path / "g1.png").exists()  # nothing ran
