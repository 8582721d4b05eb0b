"""The commands of the README's "What you can do" table run (issue #29), top to bottom as
a reader runs them, in one folder (a row's files are there for the rows below it), in
process against the emulators, as the fenced blocks do (tests/docs/runnable.py).

Each command runs without its optional parts and with each of them (tests/docs/readme_table.py).
A line that cannot run here is declared below with its reason; the test fails on a line
that neither runs nor is declared, and on a declaration that no line matches any more."""

from __future__ import annotations

import os
import shutil
import time
from collections import Counter
from pathlib import Path

import pytest
from firmware_support import build_firmware
from readme_table import Row, parse_rows, variants
from runnable import Emulators, Line, program_spec, run_line
from sybil import Sybil

from snakebot.model.robots.loader import BUILTIN_ROBOTS
from snakebot.paths import REPO_ROOT

# the lines wait on the wall clock as the fenced blocks' REAL_TIME groups do (flash, bus play)
pytestmark = [pytest.mark.timeout(180), pytest.mark.serial]

README = REPO_ROOT / "README.md"

FIELDS = "snakebot model fields snake3 --at 0,0,0,pi/3,-pi/3"
THESIS = "snakebot sim thesis -o out/thesis"
COVERED_BY_THESIS = (
    "minutes of MuJoCo: `--only h3` runs here, tests/workflows/test_physics_studies.py runs two"
)
MONITOR = "snakebot monitor --port /dev/ttyUSB0"
MONITOR_WHY = "runs until Ctrl-C (no --duration); tests/cli/test_controller_cli_monitor.py records"
COMPARE = "snakebot compare run.csv s.gait"
COMPARE_WHY = (
    "needs run.csv, which the monitor row records until Ctrl-C; `snakebot compare --help`'s "
    "example records a run with --duration and compares it"
)
VIEWER = ("window", "MuJoCo's viewer needs a desktop; tests/plots/test_viewer.py")
SIM_BUS = "snakebot sim bus --robot snake5 --pty"
SERVES = "serves until Ctrl-C; the fenced blocks' test starts the same emulators for their lines"

DECLARED: dict[str, tuple[str, str]] = {
    f"{FIELDS} --symbolic": (
        "expensive",
        "sympy simplifies snake3's fields for minutes; tests/cli/test_models_cli.py runs "
        "--symbolic on trident and car",
    ),
    "snakebot sim predict s.gait --world mujoco --video s.gif": (
        "video",
        "tens of CPU seconds of rendering; tests/plots/test_physics_video.py",
    ),
    "snakebot sim view s.gait": VIEWER,
    "snakebot sim view --port /dev/ttyUSB0 --robot snake5": VIEWER,
    THESIS: ("expensive", COVERED_BY_THESIS),
    f"{THESIS} --json": ("expensive", COVERED_BY_THESIS),
    SIM_BUS: ("until Ctrl-C", SERVES),
    f"{SIM_BUS} --world mujoco": ("until Ctrl-C", SERVES),
    "snakebot sim serve --world mujoco --foxglove 8765": (
        "until Ctrl-C",
        "serves until Ctrl-C; tests/cli/test_serve_foxglove.py",
    ),
    "snakebot bus play s.gait --port /dev/ttyUSB0 --loop": (
        "until Ctrl-C",
        "loops until Ctrl-C; the line without --loop runs, tests/cli/test_bus_play.py stops a loop",
    ),
    MONITOR: ("until Ctrl-C", MONITOR_WHY),
    f"{MONITOR} --json": ("until Ctrl-C", MONITOR_WHY),
    f"{MONITOR} --csv run.csv": ("until Ctrl-C", MONITOR_WHY),
    f"{MONITOR} --mcap run.mcap": ("until Ctrl-C", MONITOR_WHY),
    "snakebot drive --port /dev/ttyUSB0 --robot snake5": (
        "until Ctrl-C",
        "reads the keyboard until q; `snakebot drive --help`'s example runs with --keys",
    ),
    "make flash PORT=/dev/ttyUSB0": (
        "real hardware",
        "make builds, then runs `snakebot flash --port`, the row's next line, run here against "
        "the emulated bootloader",
    ),
    "snakebot doctor --port /dev/ttyUSB0 --board cm530": (
        "real hardware",
        "checks that the controller is a CM-530; the emulated controller here is the host-run "
        "logic, which names no board; tests/firmware/test_cm530_cli.py runs it on the "
        "emulated chip",
    ),
    COMPARE: ("needs a recorded run", COMPARE_WHY),
    f"{COMPARE} --plot compare.png": ("needs a recorded run", COMPARE_WHY),
    f"{COMPARE} --json": ("needs a recorded run", COMPARE_WHY),
}
"""Lines not run here: (kind, the reason), by the line as it runs."""


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
    below see what a reader who ran the command as shown has."""
    problems: list[str] = []
    emulators = Emulators(robot=row_robot(row))
    try:
        for command in row.commands:
            before = folder.with_name(f"{folder.name}-before")
            shutil.rmtree(before, ignore_errors=True)
            shutil.copytree(folder, before, symlinks=True)
            for number, text in enumerate(variants(command)):
                line = Line(text, where)
                if text in DECLARED:
                    kinds[DECLARED[text][0]] += 1
                elif line.kind != "run":
                    problems.append(f"{where}: `{text}` ({line.kind}): run it or declare it")
                else:
                    here = folder
                    if number:  # the folder as it was before the command
                        here = folder.with_name(f"{folder.name}-variant")
                        shutil.rmtree(here, ignore_errors=True)
                        shutil.copytree(before, here, symlinks=True)
                    os.chdir(here)
                    began = time.process_time()
                    problems += run_line(line, emulators)
                    cpu[text] = time.process_time() - began
                    os.chdir(folder)
                    kinds["run"] += 1
    finally:
        emulators.close()
    return problems


cpu: dict[str, float] = {}


def test_the_commands_of_the_readme_table_run(tmp_path, monkeypatch):
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
    summary = (
        f"README table: {kinds.pop('run')} lines run, "
        + ", ".join(f"{n} {kind}" for kind, n in sorted(kinds.items()))
        + f" (declared, not run); {mentions} mentions of a command's parts"
    )
    print(summary)
    for text, seconds in sorted(cpu.items(), key=lambda item: -item[1])[:5]:
        print(f"  {seconds:5.2f} s CPU  {text}")
    assert not problems, "\n".join([summary, *problems])


def test_every_declaration_is_a_line_of_the_table():
    lines = {text for _, row in rows() for c in row.commands for text in variants(c)}
    assert not set(DECLARED) - lines, set(DECLARED) - lines


def test_a_command_stands_for_each_of_its_optional_parts_once():
    command = "snakebot config --port ... [get safe-action \\| set x 1s] [--json] [FILE.bin]"
    command = command.replace("\\|", "|")  # as the table's code reads
    assert variants(command) == [
        "snakebot config --port /dev/ttyUSB0",
        "snakebot config --port /dev/ttyUSB0 get safe-action",
        "snakebot config --port /dev/ttyUSB0 set x 1s",
        "snakebot config --port /dev/ttyUSB0 --json",
    ]
