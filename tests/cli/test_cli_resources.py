"""What the long-running commands leave behind (issue #17, resources): the world's record
is bounded, work directories go on SIGHUP and after a SIGKILL, and a server's `--link` or
`--unix` path left by a SIGKILL is replaced on the next start, never one someone else made
or a live server's."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.formats.protocol import sync_write
from snakebot.model.robots import load_robot
from snakebot.sim.options import SimOptions
from snakebot.sim.qemu import DEFAULT_IMAGE
from snakebot.sim.serve import default_firmware
from snakebot.sim.workdirs import make_workdir, sweep_stale
from snakebot.sim.world import World

GOAL_AND_SPEED = 30


def _walk(keep: int | None, seconds: float) -> World:
    """snake5 on a serpenoid for ``seconds`` of bus time, its world keeping ``keep``."""
    robot = load_robot("snake5")
    bus = SimOptions(robot="snake5", ideal=True).build_bus()
    world = World(bus, robot, period=0.01, batch=64, keep=keep)
    for k, t in enumerate(np.arange(0, seconds, 0.02)):
        phi = 0.4 * np.sin(3 * t + np.arange(4) * 1.2)
        ticks = robot.angles_to_ticks(phi)
        block = {
            sid: int(g).to_bytes(2, "little") + (0).to_bytes(2, "little")
            for sid, g in zip(robot.servo_ids, ticks, strict=True)
        }
        bus.run_until(k * 0.02)
        bus.master_write(sync_write(GOAL_AND_SPEED, 4, block))
    bus.run_until(seconds)
    return world


def test_the_world_record_is_bounded_and_ends_where_the_whole_one_does():
    bounded, whole = _walk(keep=200, seconds=20.0), _walk(keep=None, seconds=20.0)
    small, full = bounded.record(), whole.record()
    assert len(full.t) == 2001
    assert 200 <= len(small.t) <= 200 + bounded.batch
    assert bounded.samples == whole.samples == 2001
    # The newest samples are the same ones, at the same times, with the same poses.
    n = len(small.t)
    assert np.array_equal(small.t, full.t[-n:])
    assert np.abs(small.pose - full.pose[-n:]).max() < 1e-12
    assert np.array_equal(bounded.pose, whole.pose)


def test_the_bounded_record_stays_small_however_long_the_world_runs():
    world = _walk(keep=100, seconds=60.0)
    assert world.samples == 6001
    assert len(world.record().t) <= 100 + world.batch
    assert world._history._rows.shape[0] == 100  # what is held (from the start), not just shown


def test_stale_work_directories_are_removed_on_the_next_start():
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = Path(tempfile.mkdtemp(prefix=f"snakebot-serve-{dead.pid}-"))
    (stale / "flash.bin").write_bytes(b"\0" * 16)
    live = Path(make_workdir("serve"))  # ours: this process is alive
    try:
        assert not stale.exists()
        assert live.is_dir() and str(os.getpid()) in live.name
        assert sweep_stale("serve") == []
    finally:
        live.rmdir()


SERVERS = {
    "sim bus --link": ["sim", "bus", "--ids", "1", "--link"],
    "sim bus --unix": ["sim", "bus", "--ids", "1", "--unix"],
    "sim bootloader --link": ["sim", "bootloader", "--link"],
}


def _start(args: list[str]) -> subprocess.Popen[str]:
    """``snakebot ARGS`` in a subprocess, once it says it serves."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "snakebot", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    while "stops." not in (line := proc.stdout.readline()):
        if not line:
            proc.wait()
            raise AssertionError(proc.stderr.read() if proc.stderr else "")
    return proc


def _stop(proc: subprocess.Popen[str]) -> None:
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def _made(path: Path) -> tuple[str, int]:
    """What is at ``path`` (the link's target, or "socket") and its inode."""
    info = os.lstat(path)
    return (os.readlink(path) if path.is_symlink() else "socket", info.st_ino)


@pytest.mark.parametrize("server", SERVERS)
def test_a_path_left_by_a_killed_server_is_replaced_and_a_live_ones_is_refused(tmp_path, server):
    # ...and SIGTERM stops the server cleanly: exit 143, its path removed.
    path = tmp_path / "ttyDXL"
    args = [*SERVERS[server], str(path)]
    first = _start(args)
    try:
        first.kill()  # no chance to clean up: the path stays
        first.wait()
        assert os.path.lexists(path)
        second = _start(args)  # the leftover of our dead server is recognised and replaced
        try:
            made = _made(path)
            live = CliRunner().invoke(main, args)
            assert live.exit_code == 2, live.output
            assert live.stderr.count("\n") == 1
            assert f"{path} is in use by a running snakebot server (pid {second.pid}" in live.stderr
            assert _made(path) == made  # the live server's path is untouched
        finally:
            second.send_signal(signal.SIGTERM)
            _, err = second.communicate(timeout=30)
        assert second.returncode == 143, err  # stopped cleanly, as SIGTERM says
        assert err.strip() == "interrupted", err
        assert not os.path.lexists(path)  # the clean stop removed it
    finally:
        _stop(first)


@pytest.mark.parametrize("server", SERVERS)
@pytest.mark.parametrize("planted", ["file", "foreign link", "dead pty link", "socket"])
def test_a_path_someone_else_made_is_refused_and_left_alone(tmp_path, server, planted):
    import socket

    path = tmp_path / "ttyDXL"
    outside = tmp_path / "precious"
    outside.write_text("keep me")
    if planted == "file":
        path.write_text("mine")
    elif planted == "foreign link":
        path.symlink_to(outside)
    elif planted == "dead pty link":  # as an older snakebot, killed, left it: no record
        path.symlink_to("/dev/pts/999999")
    else:
        socket.socket(socket.AF_UNIX).bind(str(path))
    before = os.lstat(path)
    result = CliRunner().invoke(main, [*SERVERS[server], str(path)])
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith(f"error: {SERVERS[server][-1]}: {path} ")  # the option
    assert f"rm {path}" in result.stderr and result.stderr.count("\n") == 1
    after = os.lstat(path)
    assert (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns)
    assert outside.read_text() == "keep me"


def _workdirs(pid: int) -> list[Path]:
    return [
        p
        for kind in ("serve", "qemu")
        for p in Path(tempfile.gettempdir()).glob(f"snakebot-{kind}-{pid}-*")
    ]


def _serve() -> tuple[subprocess.Popen[str], dict]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "snakebot", "sim", "serve", "--board", "qemu"]
        + ["--robot", "snake3", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert line, proc.stderr.read() if proc.stderr else ""
    return proc, json.loads(line)


@pytest.mark.qemu
@pytest.mark.skipif(not DEFAULT_IMAGE.is_file(), reason="needs `make firmware`")
@pytest.mark.parametrize("how", [signal.SIGHUP, signal.SIGKILL], ids=["SIGHUP", "SIGKILL"])
def test_sim_serve_leaves_no_work_directories(how):
    proc, info = _serve()
    try:
        assert Path(info["bus_socket"]).exists()
        assert len(_workdirs(proc.pid)) == 2  # the server's and QEMU's
        proc.send_signal(how)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    if how == signal.SIGKILL:
        assert len(_workdirs(proc.pid)) == 2  # no chance to clean up...
        sweep_stale("serve"), sweep_stale("qemu")  # ...so the next start does
    assert _workdirs(proc.pid) == []


@pytest.mark.qemu
@pytest.mark.skipif(not default_firmware().is_file(), reason="needs `make firmware`")
def test_a_served_robot_keeps_only_its_recent_history():
    import time

    from snakebot.sim.serve import EmulatedRobot

    with EmulatedRobot("snake3", history_s=0.5) as robot:
        time.sleep(4.0)  # about 400 world samples on the bus clock
        world = robot.world
        with robot.lock:  # the bus runs on in its thread: take both at one instant
            record, samples = world.record(), world.samples
        t, goals = robot.goals()
    assert samples > 50 + world.batch
    assert len(record.t) <= 50 + world.batch and len(t) == len(goals) <= 50
    assert record.t[-1] == pytest.approx((samples - 1) * world.period)
