"""Benchmark: what filming a run costs beside running it (issue #33).

A 10 s run of snake5's serpenoid on the MuJoCo world (`sim predict --world mujoco`, the
host as bus master), then its video at 1280x720 (the default) from MuJoCo's offscreen
renderer, encoded to MP4 by imageio-ffmpeg. Printed: the wall and CPU seconds of each
(CPU: this process's, which depends less on what else the shared machine runs, plus the
encoder's, a child process encoding while the next frame is drawn), their ratio, the
renderer's backend and frames a second. Goal: the video costs under 3x the simulation.

Then what no change to the drawing can go below on this machine: the renderer's time
for the emptiest picture of the robot (standing still on the floor: no path, the
overlay) and ffmpeg's time to encode such frames, each times the frames the video needs.

    .venv/bin/python bench/bench_video.py [--quick]   # --quick: 2 s at 640x360
"""

from __future__ import annotations

import math
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from snakebot.model.gait import serpenoid
from snakebot.model.robots import Robot, load_robot
from snakebot.plots import render3d
from snakebot.plots.motion import StateMotion
from snakebot.plots.video import FPS, _encoder, write_video
from snakebot.workflows.predict import predict_gait

GOAL_RATIO = 3.0
STILL_FRAMES = 20


def cpu() -> float:
    """CPU seconds of this process and of its finished children (the encoder)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def still_frame_cost(robot: Robot, size: tuple[int, int], tmp: Path) -> tuple[float, float, float]:
    """Wall and CPU seconds a frame of the robot standing still (no path) costs to draw
    and read back, and the CPU seconds it costs to encode."""
    still = StateMotion(np.zeros(1), np.zeros((1, 3)), np.zeros((1, len(robot.joints))))
    with render3d.Renderer3D(robot, size) as renderer:
        renderer.frame({"still": still}, 0.0)
        wall0, cpu0 = time.perf_counter(), time.process_time()
        frames = [renderer.frame({"still": still}, 0.0) for _ in range(STILL_FRAMES)]
        wall, draw_cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    cpu0 = cpu()
    writer = _encoder(tmp / "still.mp4", size, FPS)
    for k in range(STILL_FRAMES):
        writer.send(frames[k])
    writer.close()
    return wall / STILL_FRAMES, draw_cpu / STILL_FRAMES, (cpu() - cpu0) / STILL_FRAMES


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
        wall0, cpu0 = time.perf_counter(), cpu()
        path = write_video(Path(tmp) / "run.mp4", robot, runs, size=size)
        video_wall, video_cpu = time.perf_counter() - wall0, cpu() - cpu0
        megabytes = path.stat().st_size / 1e6
        still_wall, still_cpu, encode_cpu = still_frame_cost(robot, size, Path(tmp))
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
        f"(goal under {GOAL_RATIO:g}x: {'met' if ratio_cpu < GOAL_RATIO else 'MISS'}); "
        f"per simulated second: {video_wall / seconds:.2f} s wall, {video_cpu / seconds:.2f} s CPU"
    )
    limit_cpu = frames * (still_cpu + encode_cpu)
    print(
        f"  limit: a still frame costs {1000 * still_wall:.1f} ms wall, {1000 * still_cpu:.1f} ms "
        f"CPU to draw and {1000 * encode_cpu:.1f} ms CPU to encode; x {frames} frames = "
        f"{limit_cpu:.2f} s CPU = {limit_cpu / sim_cpu:.1f}x the simulation's CPU "
        f"(encoding alone {frames * encode_cpu / sim_cpu:.1f}x); the video is "
        f"{video_cpu / limit_cpu:.2f}x this limit"
    )


if __name__ == "__main__":
    main()
