"""`snakebot demo --json`: the whole chain on the real firmware, as `make demo` runs it (a
subprocess): the snake advances, the PNG is written, nothing is left running. The default
board (the CM-530's image on the emulated STM32F103RE, in the demo's own process) plays in
the kinematic world, the QEMU board (a process of its own) in the default one, MuJoCo's:
each board and each world once, and the heavier world beside the emulator that leaves the
demo's process a core of its own (beside another worker, the CM-530 and MuJoCo in one
process fell to 0.3x real time). Ctrl-C and a host that
deschedules the emulator are tried on QEMU, a process of its own the test can watch and
stop."""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import threading
import zlib
from collections.abc import Iterator
from pathlib import Path

import pytest
from firmware_support import build_firmware

from snakebot.sim.serve import default_firmware

pytestmark = [pytest.mark.qemu, pytest.mark.slow]

DEMO_TIMEOUT_S = 300.0  # the demo takes ~15 s; a loaded machine may be much slower
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
RUNS = 2  # a second run when the first was INVALID (the host disturbed it)


@pytest.mark.parametrize(("world", "board"), [("mujoco", "qemu"), ("kinematic", "cm530")])
def test_demo_json_reports_the_snake_advancing_and_writes_the_png(tmp_path, world, board):
    build_firmware()
    out = tmp_path / "out"
    for _ in range(RUNS):  # an INVALID run says: rerun on an idle machine
        done = subprocess.run(
            [sys.executable, "-m", "snakebot", "demo", "--json", "--cycles", "2"]
            + ["--out", str(out)]
            + ([] if world == "mujoco" else ["--world", world])
            + ["--board", board],
            capture_output=True,
            text=True,
            timeout=DEMO_TIMEOUT_S,
            check=False,
        )
        if done.returncode != 1 or json.loads(done.stdout or "{}").get("verdict") != "INVALID":
            break
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr
    result = json.loads(done.stdout)

    emulated, predicted = result["emulated"], result["predicted"]
    assert predicted["dx"] > 0.1  # the gait is one that goes somewhere: 10+ cm in 2 cycles
    assert emulated["dx"] > 0.5 * predicted["dx"]
    assert result["difference_m"] == pytest.approx(
        ((emulated["dx"] - predicted["dx"]) ** 2 + (emulated["dy"] - predicted["dy"]) ** 2) ** 0.5,
        abs=1e-5,
    )
    assert (result["world"], result["board"]) == (world, board)
    assert Path(result["firmware"]) == default_firmware(board)
    # the difference's measured parts: what the servos' lag accounts for, and the rest
    assert result["lag_part_m"] + result["after_lag_m"] >= result["difference_m"] - 1e-5
    larger = "servo lag" if result["lag_part_m"] >= result["after_lag_m"] else "the rest"
    if world == "mujoco":  # the default: the prediction's own model is not the judge
        assert result["reason"] == {"servo lag": "servo lag", "the rest": "physics"}[larger]
        physics = result["physics"]
        free = physics["predicted_free_wheels"]  # the kinematic model, the twin's free wheels
        assert physics["difference_free_wheels_m"] < 0.1 * free["distance"]
        assert sum(physics["electrical_j"]) > sum(physics["work_j"]) > 0
    else:  # the prediction's own model: only the servos' lag separates them
        assert result["reason"] == {"servo lag": "servo lag", "the rest": "tracking error"}[larger]
        assert "physics" not in result
        assert result["within_tolerance"], (result["difference_m"], result["tolerance_m"])
        assert result["verdict"] == "AGREE"
    assert result["verdict"] in ("AGREE", "DISAGREE")  # exit 0: not INVALID
    pace = result["pacing"]  # measured: a steady pace is one within both limits
    within = (
        pace["still_s"] <= pace["still_limit_s"],
        pace["leap_frames"] <= pace["leap_limit_frames"],
    )
    assert pace["steady"] == all(within) and 0 < pace["still_s"] < 10, pace
    assert result["upload"]["crc"] == f"0x{zlib.crc32((out / 'demo.gait').read_bytes()):08x}"
    assert result["monitor"]
    assert all(m["controller"]["state"] == "PLAYING" for m in result["monitor"])

    png = out / "demo.png"
    assert result["png"] == str(png)
    assert png.read_bytes()[:8] == PNG_MAGIC and png.stat().st_size > 10_000

    if board == "qemu":
        with pytest.raises(ProcessLookupError):  # QEMU was stopped and reaped
            os.kill(result["qemu_pid"], 0)


@contextlib.contextmanager
def playing_qemu_demo(
    tmp_path: Path, *options: str
) -> Iterator[tuple[subprocess.Popen, int, list[str]]]:
    """`snakebot demo --board qemu OPTIONS` in a process of its own, read until it plays:
    (the process, QEMU's pid, the lines it printed so far); killed on the way out if it
    is still running."""
    build_firmware()
    proc = subprocess.Popen(
        [sys.executable, "-m", "snakebot", "demo", *options]
        + ["--board", "qemu", "--out", str(tmp_path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        printed, qemu_pid = [], None
        for line in proc.stdout:  # until it plays
            printed.append(line)
            if found := re.search(r"QEMU \(pid (\d+)\)", line):
                qemu_pid = int(found.group(1))
            if "monitoring" in line:
                break
        assert qemu_pid is not None
        yield proc, qemu_pid, printed
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_ctrl_c_stops_the_demo_and_leaves_nothing_running(tmp_path):
    with playing_qemu_demo(tmp_path) as (proc, qemu_pid, _):
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        assert proc.returncode == 130
        assert "nothing is left running" in err
        with pytest.raises(ProcessLookupError):
            os.kill(qemu_pid, 0)


QUICK = ("--world", "kinematic", "--cycles", "1")
"""The demo's options for the runs the host disturbs: one measured cycle, no MuJoCo."""

PAUSE_S = 0.4  # longer than a steady run's goals ever stand still (STILL_LIMIT_S)
PAUSE_EVERY_S = 1.0


def test_a_run_the_host_disturbs_says_so_and_is_never_a_disagreement(tmp_path):
    """QEMU stopped (SIGSTOP) for 0.4 s every second while the firmware plays, as a busy
    host deschedules it: the report's pace line says the host disturbed it, and the
    verdict is AGREE (exit 0) if the tolerance took the disturbance in, else INVALID
    (exit 1, why, and to rerun on an idle machine), never DISAGREE
    (tests/workflows/test_demo_pace.py checks which one on made-up differences)."""
    done = threading.Event()

    def disturb(pid: int) -> None:
        while not done.wait(PAUSE_EVERY_S - PAUSE_S):
            try:
                os.kill(pid, signal.SIGSTOP)
                done.wait(PAUSE_S)
                os.kill(pid, signal.SIGCONT)
            except ProcessLookupError:
                return

    with playing_qemu_demo(tmp_path, *QUICK) as (proc, qemu_pid, printed):
        threading.Thread(target=disturb, args=(qemu_pid,), daemon=True).start()
        try:
            out, err = proc.communicate(timeout=DEMO_TIMEOUT_S)
        finally:
            done.set()
    report = "".join(printed) + out
    lines = report.splitlines()
    verdict = next(line for line in lines if "verdict:" in line)
    pace = next(line for line in lines if line.startswith("   pace:"))
    assert pace.startswith("   pace: disturbed by the host"), pace
    assert "stood still" in pace, pace
    assert "DISAGREE" not in report
    if proc.returncode == 1:
        assert verdict.startswith("5. verdict: INVALID (the host"), verdict
        assert "stood still" in verdict and "rerun on an idle machine" in verdict, verdict
    else:
        assert proc.returncode == 0, report + err
        assert verdict.startswith("5. verdict: AGREE"), verdict


def test_an_emulator_the_host_never_runs_again_is_blamed_on_the_host(tmp_path):
    """QEMU stopped (SIGSTOP) for good once the firmware plays: the PC link goes silent as
    a host overloaded far beyond the link's margins leaves it. The demo ends with one line
    that names the host's load, not the board's power or cable (exit 1), and leaves
    nothing running."""
    with playing_qemu_demo(tmp_path, *QUICK) as (proc, qemu_pid, _):
        os.kill(qemu_pid, signal.SIGSTOP)
        _, err = proc.communicate(timeout=DEMO_TIMEOUT_S)
    assert proc.returncode == 1, err
    (line,) = err.strip().splitlines()
    assert "the host did not run the emulator in time (load average" in line, line
    assert "powered" not in line and "USB cable" not in line, line
    with pytest.raises(ProcessLookupError):
        os.kill(qemu_pid, 0)
