"""Library messages speak the library's words: no module of ``host/snakebot`` outside
``cli/`` spells a command-line option (``--rate``) in a string. A message about a value
that came through a parameter says what is wrong in words and records the parameter with
``SnakebotError.about("rate")``; the CLI then names its option (``snakebot.cli.errors``).

Every string literal is read with ``ast`` (an f-string with its values as ``x``), except
docstrings, which document the command line as well as the library, and the arguments
of ``argparse`` parsers, which are command lines of their own (``python -m ...``).
Whole command lines of another command, which ``about`` cannot name, are listed in
:data:`OTHER_COMMANDS`, each with its reason."""

from __future__ import annotations

import ast
import re
from functools import cache

import pytest

from snakebot.paths import REPO_ROOT

PACKAGE = REPO_ROOT / "host" / "snakebot"
OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")
ARGPARSE_CALLS = {"ArgumentParser", "add_argument", "add_argument_group", "add_parser"}

OTHER_COMMANDS = {
    "snakebot stop --clear": "leaving the safe state takes another command than the one "
    "that met it (play, upload, library, limits)",
    "snakebot bus scan --bauds common": "a servo that does not answer at the bus's rate is "
    "found by a scan, another command than set-baud's",
    "snakebot bus scan --ids x --bauds common": "the same scan, for the one servo that "
    "set-baud lost",
    "snakebot flash --port": "the doctor names the command that installs the firmware it "
    "did not find",
    "snakebot library restore x --port x": "flash saved the library to restore it later, "
    "with another command",
    "snakebot bus scan --latency-timer": "the adapter's latency timer is lowered by the "
    "scan command, named wherever a slow adapter is met",
}
"""Command lines of another command a library message may quote -> why."""


def _text(node: ast.expr) -> str | None:
    """The text of a string literal or f-string (formatted values as ``x``)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(
            v.value if isinstance(v, ast.Constant) else "x" for v in node.values
        )  # fmt: skip
    return None


def _docstrings(tree: ast.AST) -> set[int]:
    """The ids of the nodes that are docstrings (a module's, class's, function's, and the
    attribute docstrings that follow an assignment)."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Expr) and _text(node.value) is not None:
            found.add(id(node.value))
    return found


def _argparse_args(tree: ast.AST) -> set[int]:
    """The ids of the string nodes inside argparse calls."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if name in ARGPARSE_CALLS:
                found.update(id(n) for n in ast.walk(node))
    return found


def options_in(source: str) -> list[tuple[int, str, str]]:
    """(line, option, text) of every option spelled in ``source``'s strings, but for the
    docstrings, argparse calls and :data:`OTHER_COMMANDS`."""
    tree = ast.parse(source)
    skip = _docstrings(tree) | _argparse_args(tree)
    found = []
    for node in ast.walk(tree):
        if id(node) in skip or not isinstance(node, ast.expr):
            continue
        text = _text(node)
        if text is None:
            continue
        if isinstance(node, ast.JoinedStr):
            skip.update(id(v) for v in node.values)
        for command in OTHER_COMMANDS:
            text = text.replace(command, "")
        found += [(node.lineno, option, text) for option in OPTION.findall(text)]
    return found


@cache
def library_options() -> list[str]:
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.relative_to(PACKAGE).parts[0] == "cli":
            continue
        for line, option, text in options_in(path.read_text()):
            where = path.relative_to(REPO_ROOT)
            out.append(f"{where}:{line}: {option} in {text[:80]!r}")
    return out


def test_no_library_message_spells_a_command_line_option():
    assert library_options() == [], (
        "say it in words and name the parameter with .about(...): " + "; ".join(library_options())
    )


@pytest.mark.parametrize(
    "source, spelled",
    [
        ('raise E("--rate must be positive")', ["--rate"]),
        ('raise E(f"--{name} must be finite")', ["--x"]),
        ('hint = f"lower --rate to {r}"', ["--rate"]),
        ('raise E("the rate must be positive").about("rate")', []),
        ('def f():\n    """Give --rate."""', []),
        ('p.add_argument("--robot", help="servos")', []),
        ('say("`snakebot stop --clear` leaves it")', []),
        ('say("`snakebot stop --clear --force` leaves it")', ["--force"]),
        ('x = "a -- b, --5, ---"', []),
    ],
)
def test_the_check_finds_options_and_only_options(source: str, spelled: list[str]):
    assert [option for _, option, _ in options_in(source)] == spelled


@pytest.mark.parametrize("command", sorted(OTHER_COMMANDS))
def test_every_other_command_is_still_quoted(command: str):
    """An entry of OTHER_COMMANDS that no message quotes any more is stale."""
    pattern = re.escape(command).replace("x", ".*")
    found = any(
        re.search(pattern, text)
        for path in PACKAGE.rglob("*.py")
        if path.relative_to(PACKAGE).parts[0] != "cli"
        for text in _strings(path.read_text())
    )
    assert found, f"no library message quotes {command!r}: drop it from OTHER_COMMANDS"


def _strings(source: str) -> list[str]:
    tree = ast.parse(source)
    return [t for node in ast.walk(tree) if isinstance(node, ast.expr) and (t := _text(node))]
