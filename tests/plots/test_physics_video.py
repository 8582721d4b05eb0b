"""Videos of runs from the commands that film them (small pictures: tests/plots/test_video3d.py
checks the pictures themselves), and the top view's outline of the robot."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from physics_support import snake5_serpenoid_file
from PIL import Image

from snakebot.cli import main
from snakebot.model.robots import load_robot
from snakebot.plots import video as videos
from snakebot.plots.topview import body_points
from snakebot.plots.video import GIF_FPS

pytest.importorskip("mujoco")
imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")


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
        main,
        ["sim", "predict", str(path), "--world", "mujoco", "--video", str(gif), "--size", "160x96"],
    )
    assert result.exit_code == 0, result.output
    with Image.open(gif) as image:
        assert image.format == "GIF"
        assert image.size == (160, 96)
        assert image.n_frames == 2 * GIF_FPS + 1  # 2 s at a GIF's frames a second
        first = np.asarray(image.convert("RGB"))
        image.seek(image.n_frames - 1)
        last = np.asarray(image.convert("RGB"))
    assert (first != last).any()  # the robot moved


def test_thesis_writes_one_video_per_run(tmp_path, monkeypatch):
    monkeypatch.setattr(videos, "MAX_FRAMES", 12)
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
            "--size",
            "160x96",
        ],
    )
    assert result.exit_code == 0, result.output
    for name in ("g1", "g3"):
        with Image.open(tmp_path / f"thesis-{name}.gif") as image:
            assert image.n_frames == 12


def test_goto_films_the_way_to_the_target(tmp_path, monkeypatch):
    monkeypatch.setattr(videos, "MAX_FRAMES", 12)  # the film of 13 s, shown fast
    mp4 = tmp_path / "goto.mp4"
    result = CliRunner().invoke(
        main,
        [
            "sim",
            "goto",
            "trident",
            "--to",
            "0.3,0.1,10deg",
            "--video",
            str(mp4),
            "--size",
            "160x96",
            "--json",
        ],
    )
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["video"] == str(mp4)
    assert mp4.stat().st_size > 1000
    assert sum(1 for _ in imageio_ffmpeg.read_frames(str(mp4))) - 1 == 12  # less the header


@pytest.mark.parametrize(
    ("name", "args", "words"),
    [
        ("x.gif", ["--size", "100x"], "WIDTHxHEIGHT"),
        ("x.gif", ["--size", "641x360"], "even"),
        ("x.avi", [], ".gif, .mp4"),
    ],
)
def test_goto_refuses_a_bad_video_before_the_run(tmp_path, name, args, words):
    result = CliRunner().invoke(
        main, ["sim", "goto", "trident", "--to", "0.3,0,0", "--video", str(tmp_path / name), *args]
    )
    assert result.exit_code == 2 and words in result.output
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["run.avi", "missing/run.gif"])
def test_a_video_that_cannot_be_written_is_refused_before_the_run(tmp_path, name):
    result = CliRunner().invoke(
        main,
        ["sim", "thesis", "-o", str(tmp_path), "--only", "g1", "--video", str(tmp_path / name)],
    )
    assert result.exit_code == 2
    assert result.output.startswith("error: ") and result.output.count("\n") == 1
    assert not (tmp_path / "g1.png").exists()  # nothing ran
