"""Every command the documents and the help texts show runs (issue #29) against the
emulators (tests/docs/runnable.py says how each kind of line is treated, running.py how
it runs):

* the fenced ``sh`` and ``console`` blocks of README.md and docs/*.md, read with Sybil;
* every example line (``snakebot ...``) of every command's --help.

A line for real hardware says so in the text (``# real hardware only``); a line too
costly to run in the suite is declared below (NOT_RUN) with what it costs; any other
line that cannot run here fails the test, so a change that breaks an example is caught,
and so does a declaration that no line matches any more."""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import click
import pytest
from click.testing import CliRunner
from firmware_support import build_firmware
from runnable import (
    Emulators,
    Line,
    block_lines,
    help_examples,
    program_spec,
    run_console,
)
from running import NOT_RUN, how, run_any
from sybil import Document, Sybil
from sybil.parsers.markdown import CodeBlockParser
from sybil.parsers.markdown.lexers import FencedCodeBlockLexer
from xvfb_support import display, xvfb

from snakebot.cli import main
from snakebot.paths import REPO_ROOT

pytestmark = pytest.mark.timeout(180)
__all__ = ["display", "xvfb"]  # the X server of the lines that open a window (fixtures)

COMMAND = re.compile(r"^(?:\$ )?(?:[A-Z][A-Z0-9_]*=\S* )*snakebot ")  # env words first
PAGES = [REPO_ROOT / "README.md", *sorted((REPO_ROOT / "docs").glob("*.md"))]
SYBIL = Sybil(
    parsers=[CodeBlockParser(language="sh"), CodeBlockParser(language="console")],
    path=str(REPO_ROOT),
    patterns=["README.md", "docs/*.md"],
)


def blocks(page: Path) -> list[tuple[str, str, str]]:
    """(language, source, where) of each ``sh`` or ``console`` block of ``page``."""
    found = []
    for example in SYBIL.parse(page):
        language = example.region.lexemes.get("arguments", "").strip()
        where = f"{page.relative_to(REPO_ROOT)}:{example.line}"
        found.append((language, example.parsed, where))
    return found


def help_groups() -> dict[str, list[Line]]:
    """The example lines of each command's --help, in order."""
    groups: dict[str, list[Line]] = {}
    for line in help_examples():
        groups.setdefault(line.where.split(",")[0], []).append(line)
    return groups


HELP = help_groups()

REAL_TIME = {
    "snakebot bus play --help",  # plays at the table's pace
    "snakebot compare --help",  # records a run for seconds while the controller plays
    "snakebot demo --help",  # the emulated robot plays in real time
    "snakebot drive --help",  # keys timed in seconds, a terminal's screen
    "snakebot flash --help",  # the bootloader's silences, the new firmware's boot
    "snakebot sim bootloader --help",
    "first-flash.md",
    "hardware.md",  # make flash: a flash, as first-flash.md's
    "snakebot monitor --help",  # samples at the controller's pace until Ctrl-C
    "snakebot sim serve --help",  # the emulated CM-530 in real time, a monitor
    "snakebot foxglove-layout --help",  # sim serve, as above
    "snakebot sim bus --help",  # servos replying in real time
    "snakebot sim view --help",  # a window drawn by its own thread, runs shown in real time
}
"""Groups whose commands wait on the wall clock: `make test` runs them with the tests
marked serial, after the CPU-bound ones."""


def params(names: list[str]) -> list[object]:
    return [pytest.param(n, marks=pytest.mark.serial) if n in REAL_TIME else n for n in names]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    """The files the examples name, made as the documents make them."""
    build_firmware()
    folder = tmp_path_factory.mktemp("docs")
    (folder / "build").symlink_to(REPO_ROOT / "build")  # `make firmware`'s images
    for args in (
        ["gait", "serpenoid", "snake5", "-A", "30deg", "-w", "180deg", "-d", "90deg"]
        + ["--cycles", "2", "-o", str(folder / "walk.gait")],
        ["robot", "new", str(folder / "my_snake.toml")],
    ):
        assert CliRunner().invoke(main, args).exit_code == 0
    for name in ("s.gait", "crawl.gait"):
        (folder / name).write_bytes((folder / "walk.gait").read_bytes())
    (folder / "plan.toml").write_text(program_spec())
    return folder


NOT_RUN_HERE: dict[str, str] = {}
"""Lines not run (but for real hardware's, marked in the text), with the reason."""


def check(lines: list[Line]) -> list[str]:
    emulators = Emulators()
    problems = []
    try:
        for line in lines:
            if line.kind == "unmarked":
                problems.append(
                    f"{line.where}: `{line.text}` cannot run here: make it run, or mark it "
                    "`# real hardware only`"
                )
            elif line.kind not in NOT_RUN:
                problems += run_any(line, emulators)[1]
            elif line.kind != "hardware" and line.text not in NOT_RUN_HERE:
                problems.append(f"{line.where}: `{line.text}` ({line.kind}): run it or declare it")
    finally:
        emulators.close()
    return problems


def needs_display(lines: list[Line], request: pytest.FixtureRequest) -> None:
    """An X server of the test's as the display, for lines that open a window."""
    if any(line.kind == "window" for line in lines):
        request.getfixturevalue("display")


@pytest.mark.parametrize("command", params(sorted(HELP)))
def test_the_examples_in_a_help_text_run(command, workdir, monkeypatch, request):
    monkeypatch.chdir(workdir)
    needs_display(HELP[command], request)
    problems = check(HELP[command])
    assert not problems, "\n".join(problems)


NO_EXAMPLE_YET: dict[str, str] = {}
"""Commands whose --help shows no example yet, and why."""


def test_every_command_shows_an_example_of_itself():
    """In its own --help, or in its group's (`snakebot library --help` shows each of its
    commands at work, one after the other)."""
    shown: dict[str, set[str]] = {}
    for line in help_examples():
        shown.setdefault(line.where.split(",")[0].removesuffix(" --help"), set()).add(line.text)

    def leaves(cmd: click.Command, path: list[str]) -> list[tuple[str, str]]:
        if not isinstance(cmd, click.Group):
            return [(" ".join(["snakebot", *path]), " ".join(["snakebot", *path[:-1]]))]
        ctx = click.Context(cmd)
        return [
            leaf
            for name in cmd.list_commands(ctx)
            for leaf in leaves(cmd.get_command(ctx, name), [*path, name])  # type: ignore[arg-type]
        ]

    missing = {
        command
        for command, group in leaves(main, [])
        if not any(
            text == command or text.startswith(f"{command} ")
            for text in shown.get(command, set()) | shown.get(group, set())
        )
    }
    assert missing == set(NO_EXAMPLE_YET), missing ^ set(NO_EXAMPLE_YET)


@pytest.mark.parametrize("name", params([p.name for p in PAGES]))
def test_the_commands_in_a_page_run(name, workdir, monkeypatch, request):
    page = next(p for p in PAGES if p.name == name)
    monkeypatch.chdir(workdir)
    needs_display([line for _, s, w in blocks(page) for line in block_lines(s, w)], request)
    problems: list[str] = []
    for language, source, where in blocks(page):
        if language == "console":
            emulators = Emulators()
            try:
                problems += run_console(source, where, emulators)
            finally:
                emulators.close()
        else:
            problems += check(list(block_lines(source, where)))
    assert not problems, "\n".join(problems)


def shown_lines() -> Iterator[tuple[str, Line]]:
    """("help" or "docs", line) of every line the help texts and the documents show."""
    for lines in HELP.values():
        yield from (("help", line) for line in lines)
    for page in PAGES:
        for language, source, where in blocks(page):
            for line in block_lines(source, where):
                if language == "sh" or line.text.startswith("$ "):
                    yield "docs", line


def inventory() -> Counter[str]:
    """How many lines the documents and the help texts show, by how they run here (or
    the kind of those not run)."""
    return Counter(f"{source}: {how(line)}" for source, line in shown_lines())


def test_a_block_of_snakebot_commands_is_marked_as_shell():
    """A fenced block whose lines are snakebot commands says it is shell (``sh`` or
    ``console``), so that the test above runs it."""
    untagged = []
    for page in PAGES:
        for region in FencedCodeBlockLexer(language=r".*")(Document.parse(str(page))):
            language = region.lexemes.get("language", "").strip()
            lines = str(region.lexemes["source"]).splitlines()
            if language not in ("sh", "console") and any(map(COMMAND.match, lines)):
                untagged.append(f"{page.name}:{region.start}")
    assert not untagged, f"fenced blocks of commands without ```sh: {untagged}"


def test_every_line_is_run_or_marked():
    kinds = inventory()
    print(", ".join(f"{n} {kind}" for kind, n in sorted(kinds.items())))
    assert kinds["help: run"] >= 50 and kinds["docs: run"] >= 2, kinds
    assert not kinds["help: unmarked"] and not kinds["docs: unmarked"], kinds


def test_every_declaration_is_a_line_shown():
    shown = {line.text for _, line in shown_lines()}
    assert not set(NOT_RUN_HERE) - shown, set(NOT_RUN_HERE) - shown
