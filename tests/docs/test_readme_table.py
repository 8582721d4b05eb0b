"""The commands of the README's "What you can do" table run (issue #29), top to bottom as
a reader runs them, in one folder (a row's files are there for the rows below it), in
process against the emulators, as the fenced blocks do (tests/docs/runnable.py).

Each command runs without its optional parts and with each of them (tests/docs/readme_table.py).
A line runs as its kind does (tests/docs/running.py): one that runs until Ctrl-C gets one
once it has done its job (an emulator answering on the port it printed, a bus played, a
window drawn; a `monitor` after CTRL_C_AFTER seconds) and must exit 130 with what it
recorded complete; `drive` runs in a terminal, `make flash` by make. Some lines' output
is checked too (CHECKS). A line that cannot run here is declared below with its reason;
the test fails on a line that neither runs nor is declared, and on a declaration that no
line matches any more."""

from __future__ import annotations

import csv
import json
import os
import shutil
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import pytest
from click.testing import Result
from firmware_support import build_firmware
from readme_table import Row, parse_rows, variants
from runnable import Emulators, Line, program_spec, run_line
from running import NOT_RUN, how, run_any
from stopping import Timed, ctrl_c
from sybil import Sybil
from xvfb_support import display, xvfb

from snakebot.link.controller.monitor import CSV_COLUMNS
from snakebot.model.robots import load_robot
from snakebot.model.robots.loader import BUILTIN_ROBOTS
from snakebot.paths import REPO_ROOT
from snakebot.workflows.thesis import RUN_NAMES

# the lines wait on the wall clock as the fenced blocks' REAL_TIME groups do (flash, bus play)
pytestmark = pytest.mark.timeout(240)
__all__ = ["display", "xvfb"]  # the X server of `sim view`'s window (fixtures)

README = REPO_ROOT / "README.md"
PNG = b"\x89PNG\r\n\x1a\n"

FIELDS = "snakebot model fields snake3 --at 0,0,0,pi/3,-pi/3"
THESIS = "snakebot sim thesis -o out/thesis"
MONITOR = "snakebot monitor --port /dev/ttyUSB0"
COMPARE = "snakebot compare run.csv s.gait"
VIEW_PORT = "snakebot sim view --port /dev/ttyUSB0 --robot snake5"
GAIT = "snakebot gait serpenoid snake5 -A 30deg -w 3 -d 60deg --cycles 2 -o s.gait"

DECLARED: dict[str, tuple[str, str]] = {}
"""Lines not run here: (kind, the reason), by the line as it runs."""

APART = {
    f"{FIELDS} --symbolic": "sympy simplifies snake3's fields: about 5 CPU seconds",
    "snakebot sim predict s.gait --world mujoco --video s.gif": "renders a video: about 4",
    THESIS: "its 7 studies in both worlds: about 5",
    f"{THESIS} --json": "the same studies: about 5",
}
"""Lines that cost many CPU seconds and need nothing of the rows above them but the
README's s.gait (GAIT): they run in the suite's parallel stage
(test_a_costly_line_of_the_readme_table_runs), not in the table's run, which waits on the
wall clock and runs alone; with what each costs."""

CTRL_C_AFTER = 2.0
"""Seconds a `monitor` line (its CHECKS read what it recorded) runs before it gets Ctrl-C:
four samples at its default interval (0.5 s), more than the three `compare` needs."""

PLAYING = ("snakebot upload s.gait --port /dev/ttyUSB0", "snakebot play --port /dev/ttyUSB0 --loop")
BEFORE: dict[str, tuple[str, ...]] = {
    # the monitor records a gait being played, as `snakebot compare --help` shows
    MONITOR: PLAYING,
    # the viewer mirrors a controller playing a gait, as `snakebot sim view --help` shows
    VIEW_PORT: PLAYING,
}
"""What a reader does on the row's controller before a command, by the command's first line."""

SNAKE5 = load_robot("snake5")
JOINTS = [joint.name for joint in SNAKE5.joints]


def samples(result: Result, here: Path) -> list[str]:
    """The monitor printed samples of the controller playing the gait."""
    count = result.stdout.count("state PLAYING")
    return [] if count >= 2 else [f"{count} samples of the controller playing: {result.stdout}"]


def json_lines(result: Result, here: Path) -> list[str]:
    """One JSON record per sample, each with the controller playing and every servo."""
    records = [json.loads(line) for line in result.stdout.splitlines()]
    if len(records) < 2:
        return [f"{len(records)} JSON records"]
    return [
        f"a record of {r['controller']['state']} with servos {[s['name'] for s in r['servos']]}"
        for r in records
        if r["controller"]["state"] != "PLAYING" or [s["name"] for s in r["servos"]] != JOINTS
    ]


def csv_rows(here: Path) -> list[dict[str, str]]:
    with (here / "run.csv").open(newline="") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
    if tuple(reader.fieldnames or ()) != CSV_COLUMNS:
        raise AssertionError(f"run.csv's header is {reader.fieldnames}")
    return rows


def csv_complete(result: Result, here: Path) -> list[str]:
    """run.csv: its header, then every sample whole (a row per servo, every column)."""
    rows = csv_rows(here)
    by_time: dict[str, list[str]] = {}
    for row in rows:
        if None in row or None in row.values():
            return [f"run.csv has a row cut short or too long: {row}"]
        by_time.setdefault(row["t"], []).append(row["name"])
    if len(by_time) < 3:
        return [f"run.csv holds {len(by_time)} samples"]
    return [
        f"run.csv's sample at t = {t}: {names}" for t, names in by_time.items() if names != JOINTS
    ]


def mcap_complete(result: Result, here: Path) -> list[str]:
    """run.mcap: the mcap library reads it to its end, one telemetry message a sample."""
    from mcap.reader import make_reader

    with (here / "run.mcap").open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        messages = list(reader.iter_messages(topics=["/snakebot/telemetry"]))
    if summary is None or len(messages) < 3:
        return [f"run.mcap: summary {summary is not None}, {len(messages)} telemetry messages"]
    return []


def compare_text(result: Result, here: Path) -> list[str]:
    """The report lines the run up by the controller's frame and gives each joint's error."""
    out = result.stdout
    want = ["lined up by the controller goals", *(f"{j}  RMS" for j in JOINTS)]
    return [f"compare did not print {w!r}: {out}" for w in want if w not in out]


def compare_plot(result: Result, here: Path) -> list[str]:
    picture = here / "compare.png"
    if not picture.read_bytes().startswith(PNG):
        return ["compare.png is not a PNG"]
    return [] if "wrote compare.png" in result.stdout else [f"no `wrote`: {result.stdout}"]


def compare_json(result: Result, here: Path) -> list[str]:
    """The JSON counts the run's samples and gives each of the gait's joints an error in
    degrees, a few (the emulated servos' lag; here 1-5), not the tens that a run lined up
    wrong or of another gait shows (the gait swings each joint 30 degrees either way)."""
    summary = json.loads(result.stdout)
    recorded = len({row["t"] for row in csv_rows(here)})
    joints = {j["joint"]: j["rms_deg"] for j in summary["joints"]}
    if summary["samples"] != recorded or list(joints) != JOINTS:
        return [f"compare --json: {summary['samples']} samples of {recorded}, joints {joints}"]
    return [f"{j}: RMS {rms} deg" for j, rms in joints.items() if not 0 <= rms < 10]


CHECKS: dict[str, Callable[[Result, Path], list[str]]] = {
    MONITOR: samples,
    f"{MONITOR} --json": json_lines,
    f"{MONITOR} --csv run.csv": csv_complete,
    f"{MONITOR} --mcap run.mcap": mcap_complete,
    COMPARE: compare_text,
    f"{COMPARE} --plot compare.png": compare_plot,
    f"{COMPARE} --json": compare_json,
}
"""What a line must have printed or written, besides exiting as it should."""


def rows() -> list[tuple[int, Row]]:
    """(line number, row) of each row of README.md's task table, read with Sybil."""
    sybil = Sybil(parsers=[parse_rows], path=str(REPO_ROOT), patterns=["README.md"])
    return [(example.line, example.parsed) for example in sybil.parse(README)]


def row_robot(row: Row) -> str:
    """The robot a row's commands name (its board has that robot's servos)."""
    words = " ".join(row.commands).split()
    return next((w for w in words if w in BUILTIN_ROBOTS), "snake5")


def run_row(row: Row, where: str, folder: Path, kinds: Counter[str]) -> list[str]:
    """Run the lines of a row in ``folder`` on a board of their own (the row's robot);
    a command's variants after the first run in a copy of the folder, so that the rows
    below see what a reader who ran the command as shown has, and the files a variant
    made that the folder lacks (`monitor --csv run.csv`'s) join it."""
    problems: list[str] = []
    emulators = Emulators(robot=row_robot(row))
    try:
        for command in row.commands:
            before = folder.with_name(f"{folder.name}-before")
            shutil.rmtree(before, ignore_errors=True)
            shutil.copytree(folder, before, symlinks=True)
            for step in BEFORE.get(variants(command)[0], ()):
                problems += run_line(Line(step, f"{where} (before)"), emulators)[1]
            for number, text in enumerate(variants(command)):
                line = Line(text, where)
                if text in DECLARED:
                    kinds[DECLARED[text][0]] += 1
                elif text in APART:
                    kinds["run apart (parallel stage)"] += 1
                elif line.kind in NOT_RUN or line.kind == "unmarked":
                    problems.append(f"{where}: `{text}` ({line.kind}): run it or declare it")
                else:
                    here = folder
                    if number:  # the folder as it was before the command
                        here = folder.with_name(f"{folder.name}-variant")
                        shutil.rmtree(here, ignore_errors=True)
                        shutil.copytree(before, here, symlinks=True)
                    os.chdir(here)
                    began = time.process_time(), time.monotonic()
                    problems += run_checked(line, here, emulators)
                    cost[text] = time.process_time() - began[0], time.monotonic() - began[1]
                    os.chdir(folder)
                    for made in here.iterdir():
                        if not (folder / made.name).exists():
                            shutil.move(made, folder / made.name)
                    kinds[how(line)] += 1
    finally:
        emulators.close()
    return problems


def run_checked(line: Line, here: Path, emulators: Emulators) -> list[str]:
    """Run a line as its kind runs (a `monitor`: Ctrl-C after CTRL_C_AFTER seconds), then
    its CHECKS."""
    if line.kind == "until Ctrl-C" and line.text in CHECKS:
        result, problems = ctrl_c(line, emulators, lambda words: Timed(seconds=CTRL_C_AFTER))
    else:
        result, problems = run_any(line, emulators)
    if problems or result is None or line.text not in CHECKS:
        return problems
    return [f"{line.where}: `{line.text}`: {p}" for p in CHECKS[line.text](result, here)]


cost: dict[str, tuple[float, float]] = {}
"""Each line's CPU seconds (this process's, its emulators' threads included) and wall
seconds."""


@pytest.mark.serial
def test_the_commands_of_the_readme_table_run(tmp_path, monkeypatch, display):
    build_firmware()
    folder = tmp_path / "reader"
    folder.mkdir()
    monkeypatch.chdir(folder)
    (folder / "build").symlink_to(REPO_ROOT / "build")  # `make firmware`'s images
    # the README's plan.toml: the spec `program build --help` shows, its table s.gait
    (folder / "plan.toml").write_text(program_spec().replace("walk.gait", "s.gait"))
    kinds: Counter[str] = Counter()
    problems: list[str] = []
    for number, row in rows():
        problems += run_row(row, f"README.md:{number}", folder, kinds)
    mentions = sum(len(row.mentions) for _, row in rows())
    ran = {kind: n for kind, n in kinds.items() if kind.startswith("run")}
    declared = {kind: n for kind, n in kinds.items() if kind not in ran}
    summary = (
        "README table: "
        + ", ".join(f"{n} {kind}" for kind, n in sorted(ran.items()))
        + "; not run: "
        + (", ".join(f"{n} {kind}" for kind, n in sorted(declared.items())) or "none")
        + f" (declared); {mentions} mentions of a command's parts"
    )
    print(summary)
    for text, (cpu, wall) in sorted(cost.items(), key=lambda item: -item[1][1])[:8]:
        print(f"  {cpu:5.2f} s CPU {wall:5.2f} s wall  {text}")
    assert not problems, "\n".join([summary, *problems])


def table_lines() -> set[str]:
    return {text for _, row in rows() for c in row.commands for text in variants(c)}


def test_every_declaration_is_a_line_of_the_table():
    missing = (set(DECLARED) | set(APART) | {GAIT}) - table_lines()
    assert not missing, missing


def thesis_written(result: Result, here: Path) -> list[str]:
    """`sim thesis -o out/thesis` wrote a picture per run (NAME.png), each a PNG."""
    made = {p.stem: p.read_bytes()[:8] for p in (here / "out" / "thesis").glob("*.png")}
    problems = [f"{name}.png is not a PNG" for name, head in made.items() if head != PNG]
    return problems + ([] if set(made) == set(RUN_NAMES) else [f"pictures of {sorted(made)}"])


def thesis_json(result: Result, here: Path) -> list[str]:
    """One record per run, each run in both worlds."""
    text = result.stdout
    return [] if all(f'"{name}"' in text for name in RUN_NAMES) else [f"--json: {text[:300]}"]


def symbolic_fields(result: Result, here: Path) -> list[str]:
    """The simplified fields of every vector field, in the joints' angles."""
    out = result.stdout
    return [f"--symbolic did not print {w!r}" for w in ("g1", "h3", "phi1") if w not in out]


APART_CHECKS: dict[str, Callable[[Result, Path], list[str]]] = {
    THESIS: thesis_written,
    f"{THESIS} --json": thesis_json,
    f"{FIELDS} --symbolic": symbolic_fields,
}
"""What an APART line must have printed or written (a video line: its video decodes)."""


@pytest.mark.parametrize("text", sorted(APART))
def test_a_costly_line_of_the_readme_table_runs(text, tmp_path, monkeypatch):
    """As a reader runs it, after the README's GAIT line made s.gait."""
    monkeypatch.chdir(tmp_path)
    emulators = Emulators()
    try:
        problems = run_line(Line(GAIT, "README.md (s.gait)"), emulators)[1]
        line = Line(text, "README.md")
        result, found = run_any(line, emulators)
        problems += found
        if not found and result is not None and text in APART_CHECKS:
            problems += [f"`{text}`: {p}" for p in APART_CHECKS[text](result, tmp_path)]
    finally:
        emulators.close()
    assert not problems, "\n".join(problems)


def test_a_command_stands_for_each_of_its_optional_parts_once():
    command = "snakebot config --port ... [get safe-action \\| set x 1s] [--json] [FILE.bin]"
    command = command.replace("\\|", "|")  # as the table's code reads
    assert variants(command) == [
        "snakebot config --port /dev/ttyUSB0",
        "snakebot config --port /dev/ttyUSB0 get safe-action",
        "snakebot config --port /dev/ttyUSB0 set x 1s",
        "snakebot config --port /dev/ttyUSB0 --json",
    ]
