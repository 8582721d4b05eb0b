"""`snakebot bus play`: the host as bus master, running the controller's gait player,
on the emulated bus in process (sim://) and on a pseudo-terminal in real time."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from click.testing import CliRunner

import snakebot.link.transport.ports  # noqa: F401  (registers sim://)
from snakebot.cli import main
from snakebot.formats.gaittable import GaitTable, read_gait, write_gait
from snakebot.model.player import TICK_MS
from snakebot.sim.options import SimOptions
from snakebot.sim.transports import PtyServer

pytestmark = pytest.mark.timeout(120)

FRAMES = np.array([[500, 600], [560, 640], [620, 700]], dtype=np.uint16)
LIMITS = ((0, 1023), (0, 1023))
PERIOD_MS = 100


def gait_file(tmp_path, loop: bool):
    path = tmp_path / ("loop.gait" if loop else "once.gait")
    write_gait(path, GaitTable((1, 2), PERIOD_MS, loop, LIMITS, FRAMES))
    return str(path)


def test_play_once_ends_on_the_last_frame(tmp_path):
    result = CliRunner().invoke(
        main,
        ["bus", "play", gait_file(tmp_path, False), "--port", "sim://?ids=1,2&ideal=1"]
        + ["--json"],
    )
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["present_position"] == {"1": 620, "2": 700}
    # one tick per 10 ms over the 200 ms pass, both ends included
    assert report["ticks"] == (len(FRAMES) - 1) * PERIOD_MS // TICK_MS + 1
    assert report["stopped_by_user"] is False
    text = CliRunner().invoke(
        main, ["bus", "play", gait_file(tmp_path, False), "--port", "sim://?ids=1,2&ideal=1"]
    )
    assert "the servos hold at tick 620 (servo 1), tick 700 (servo 2)" in text.stdout, text.output


def test_loop_needs_a_looping_gait(tmp_path):
    result = CliRunner().invoke(
        main, ["bus", "play", gait_file(tmp_path, False), "--port", "sim://?ids=1,2", "--loop"]
    )
    assert result.exit_code == 2
    assert result.stderr.startswith("error: --loop: ") and "play it once" in result.stderr


def test_play_refuses_when_a_servo_of_the_gait_is_missing(tmp_path):
    result = CliRunner().invoke(
        main, ["bus", "play", gait_file(tmp_path, True), "--port", "sim://?ids=1"]
    )
    assert result.exit_code == 2
    assert "servo 2 of the gait does not answer" in result.stderr


@pytest.mark.serial  # a real-time pty run: the stop's timing suffers beside another worker
def test_ctrl_c_on_a_pty_stops_smoothly_and_the_servos_hold(tmp_path):
    path = gait_file(tmp_path, True)
    with PtyServer(SimOptions.from_query("ids=1,2").build_bus()) as server:
        play = subprocess.Popen(
            [sys.executable, "-m", "snakebot", "bus", "play", path, "--loop", "--json"]
            + ["--port", server.device],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            # the servos answer (no silent ID costs this wait), so a wide allowance is free
            # and keeps a pty server starved by a busy machine from looking like no servo
            env={**os.environ, "SNAKEBOT_LATENCY_MS": "500"},
        )
        # Ctrl-C once the player has sent more than two passes' worth of ticks (counted
        # on the bus, so a slow start on a busy machine does not matter)
        pass_ticks = (len(FRAMES) * PERIOD_MS) // TICK_MS
        deadline = time.monotonic() + 60
        while server.bus.stats.instructions < 2 * pass_ticks and time.monotonic() < deadline:
            assert play.poll() is None, play.communicate()[1]
            time.sleep(0.05)
        assert play.poll() is None  # --loop plays until stopped
        play.send_signal(signal.SIGINT)
        out, err = play.communicate(timeout=30)
        assert play.returncode == 130, err
        assert "Traceback" not in err
        report = json.loads(out)
        assert report["stopped_by_user"] is True
        held = report["present_position"]
        time.sleep(0.3)
        after = server.bus.positions([1, 2])
    # the servos stopped inside the gait's range and stayed there
    for sid, (low, high) in zip(("1", "2"), ((500, 620), (600, 700)), strict=True):
        assert low - 2 <= held[sid] <= high + 2
    assert np.allclose(after, [held["1"], held["2"]], atol=2)


def readme_gait(runner: CliRunner, folder) -> str:
    """The README's serpenoid gait for snake5, one cycle, written in ``folder``."""
    gait = str(folder / "s.gait")
    made = runner.invoke(
        main,
        ["gait", "serpenoid", "snake5", "-A", "30deg", "-w", "360deg", "-d", "60deg"]
        + ["--cycles", "1", "-o", gait],
    )
    assert made.exit_code == 0, made.output
    return gait


def test_a_generated_gait_plays_on_the_emulated_robot(tmp_path):
    """The README's path: a serpenoid gait for snake5 played on sim://?robot=snake5 (servos
    that move at their own speed, no ideal jumps). The player only writes while it plays;
    the emulated bus must not let those writes pile up ahead of the READ that follows."""
    runner = CliRunner()
    gait = readme_gait(runner, tmp_path)
    result = runner.invoke(main, ["bus", "play", gait, "--port", "sim://?robot=snake5", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["stopped_by_user"] is False
    last = read_gait(gait).frames[-1]
    held = [report["present_position"][str(sid)] for sid in (10, 11, 15, 16)]
    # the servos followed the gait in real time: each ends near the last frame's goal
    # (an AX-12 lags its goal by a few ticks at the gait's speed)
    assert all(abs(h - int(g)) <= 25 for h, g in zip(held, last, strict=True)), (held, last)
    assert report["host_late_ms"] < 1000 * 5  # reported, in milliseconds


def test_a_host_that_stalls_mid_gait_still_leaves_the_servos_at_the_last_goal(
    tmp_path, monkeypatch
):
    """A busy host sends late ticks at once; the servos, told each frame's speed, lag the
    gait by the time lost (without the end's catch-up they held 60-134 ticks off). The
    player ends with them at the last goal and says how late it was."""
    from snakebot.model.player import TablePlayer

    runner = CliRunner()
    gait = readme_gait(runner, tmp_path)
    stall_s, stall_at_ms = 0.3, 500
    tick = TablePlayer.tick

    def stalling_tick(self, now_ms):
        if now_ms == stall_at_ms:
            time.sleep(stall_s)  # the host descheduled, as beside other work
        return tick(self, now_ms)

    monkeypatch.setattr(TablePlayer, "tick", stalling_tick)
    result = runner.invoke(main, ["bus", "play", gait, "--port", "sim://?robot=snake5", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["host_late_ms"] >= stall_s * 1000
    assert report["moved_to_last_goal"] is True
    last = read_gait(gait).frames[-1]
    held = [report["present_position"][str(sid)] for sid in (10, 11, 15, 16)]
    assert all(abs(h - int(g)) <= 3 for h, g in zip(held, last, strict=True)), (held, last)
    text = runner.invoke(main, ["bus", "play", gait, "--port", "sim://?robot=snake5"])
    assert "behind the gait" in text.output and "brought to its last goal" in text.output
