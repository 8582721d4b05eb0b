"""Benchmark: what filming a run costs beside running it (issue #33).

A 10 s run of snake5's serpenoid on the MuJoCo world (`sim predict --world mujoco`, the
host as bus master), then its video at 1280x720 (the default) from MuJoCo's offscreen
renderer, encoded to MP4 by imageio-ffmpeg. Printed: the wall and CPU seconds of each
(CPU: this process's, which depends less on what else the shared machine runs; the
encoder is a child process, counted in the wall time), their ratio, the renderer's
backend and frames a second. Goal: the video costs under 3x the simulation.

    .venv/bin/python bench/bench_video.py [--quick]   # --quick: 2 s at 640x360
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

from snakebot.model.gait import serpenoid
from snakebot.model.robots import load_robot
from snakebot.plots import render3d
from snakebot.plots.motion import StateMotion
from snakebot.plots.video import FPS, write_video
from snakebot.workflows.predict import predict_gait

GOAL_RATIO = 3.0


def main() -> None:
    quick = "--quick" in sys.argv
    seconds, size = (2, (640, 360)) if quick else (10, (1280, 720))
    robot = load_robot("snake5")
    table = serpenoid(
        robot, math.radians(30), math.pi, math.pi / 2, cycles=seconds // 2, rate_hz=50
    ).gait_table()
    wall0, cpu0 = time.perf_counter(), time.process_time()
    result = predict_gait(table, "snake5", world="mujoco")
    sim_wall, sim_cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    runs = {
        "emulated (mujoco)": result.emulated,
        "predicted": StateMotion.of_states(result.predicted.t, result.predicted.q),
    }
    with render3d.Renderer3D(robot, size) as renderer:
        backend = renderer.backend
    with tempfile.TemporaryDirectory() as tmp:
        wall0, cpu0 = time.perf_counter(), time.process_time()
        path = write_video(Path(tmp) / "run.mp4", robot, runs, size=size)
        video_wall, video_cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        megabytes = path.stat().st_size / 1e6
    frames = int(seconds * FPS) + 1
    print(f"run: {seconds} s of snake5 on the MuJoCo world, {size[0]}x{size[1]} video, {backend}")
    print(f"  simulation  {sim_wall:7.2f} s wall  {sim_cpu:7.2f} s CPU")
    print(
        f"  video       {video_wall:7.2f} s wall  {video_cpu:7.2f} s CPU  "
        f"({frames} frames, {frames / video_wall:.1f} frames/s, {megabytes:.1f} MB)"
    )
    ratio_wall, ratio_cpu = video_wall / sim_wall, video_cpu / sim_cpu
    print(
        f"  video / simulation: {ratio_wall:.1f}x wall, {ratio_cpu:.1f}x CPU "
        f"(goal under {GOAL_RATIO:g}x); per simulated second: {video_wall / seconds:.2f} s "
        f"wall, {video_cpu / seconds:.2f} s CPU"
    )


if __name__ == "__main__":
    main()
