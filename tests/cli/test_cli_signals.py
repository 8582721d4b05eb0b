"""Real signals to real snakebot processes (issue #28): SIGINT and SIGTERM stop a
command the same clean way, with 130 and 143; a recording keeps what it recorded
(``monitor --csv`` every row, ``--mcap`` every chunk, even after SIGKILL); Ctrl-C during
start-up prints no traceback."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from snakebot.workflows.compare import load_run

STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143}


def _monitor(device: str, *record: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "snakebot", "monitor", "--port", device, "--json"]
        + ["--interval", "0.05", *record],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _samples(proc: subprocess.Popen[str], count: int) -> None:
    assert proc.stdout is not None
    for _ in range(count):
        line = proc.stdout.readline()
        assert line.startswith("{"), (line, proc.stderr.read() if proc.stderr else "")


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_monitor_stops_cleanly_and_keeps_every_row(controller_with_table, tmp_path: Path, signum):
    rows, run = tmp_path / "run.csv", tmp_path / "run.mcap"
    proc = _monitor(controller_with_table.device, "--csv", str(rows), "--mcap", str(run))
    try:
        _samples(proc, 5)
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == STATUS[signum], err
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "interrupted"
    with rows.open(newline="") as f:
        table = list(csv.DictReader(f))
    assert len(table) >= 5 and all(None not in r.values() for r in table)  # no cut row
    assert len(load_run(run).t) == len(load_run(rows).t)  # closed: every sample in both


def test_monitor_mcap_cut_by_sigkill_keeps_all_but_the_last_second(controller_with_table, tmp_path):
    run = tmp_path / "run.mcap"
    proc = subprocess.Popen(  # stdout not read: it must not fill a pipe and stall monitor
        [sys.executable, "-m", "snakebot", "monitor", "--port", controller_with_table.device]
        + ["--interval", "0.05", "--mcap", str(run)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        deadline, sizes = time.monotonic() + 60, set()
        while len(sizes - {0}) < 2 and time.monotonic() < deadline:  # header, 1st chunk
            sizes.add(run.stat().st_size if run.exists() else 0)
            time.sleep(0.05)
        time.sleep(3)
        proc.kill()
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert run.stat().st_size > 0
    recorded = load_run(run)  # no index, no footer: read as a stream
    assert recorded.t[-1] - recorded.t[0] >= 2.5, recorded.t  # 4 s or more recorded


def test_ctrl_c_while_importing_prints_no_traceback():
    # The entry point, with a line printed as it starts to import the CLI (an audit hook
    # on the import: a second or more on a loaded machine), so Ctrl-C lands in the imports.
    script = (
        "import sys, snakebot.__main__ as entry; sys.argv = ['snakebot', 'gait', '--help']; "
        "sys.addaudithook(lambda event, args: event == 'import' and args[0] == 'snakebot.cli' "
        "and print('importing', flush=True)); entry.run()"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None and proc.stdout.readline() == "importing\n"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert "Traceback" not in err, err
    assert proc.returncode in (0, 130), (proc.returncode, err)  # 0: the imports won the race
    if proc.returncode == 130:
        assert err.strip() == "interrupted"


def test_sigterm_during_a_search_exits_143_and_leaves_no_partial_file(tmp_path):
    results, best = tmp_path / "runs.csv", tmp_path / "best.gait"
    proc = subprocess.Popen(
        [sys.executable, "-m", "snakebot", "gait", "search", "snake3"]
        + ["--param", "A=10deg:40deg:300", "--param", "delta=30deg:150deg:300"]
        + ["--param", "omega=180deg", "--workers", "1", "-o", str(results)]
        + ["--best", str(best)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "COLUMNS": "80"},
    )
    deadline = time.monotonic() + 120
    while not results.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.2)  # the first checkpoint is written
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert "Traceback" not in err
    assert not best.exists()
    leftovers = [p.name for p in tmp_path.iterdir() if p.name not in ("runs.csv",)]
    assert leftovers == [], leftovers
    if results.exists():  # a checkpoint: whole, and a search resumes from it
        with results.open(newline="") as f:
            assert list(csv.DictReader(f))
