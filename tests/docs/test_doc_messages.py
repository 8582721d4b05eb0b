"""The error messages the documents quote are the ones the code prints: every heading of
docs/troubleshooting.md and every message in the failure table of docs/first-flash.md
is found among the messages in host/snakebot (``...`` standing for what the code fills
in), so a reworded message cannot leave its entry behind.

The troubleshooting page's headings are the CLI's table of error codes
(``snakebot.cli.troubleshooting.ENTRIES``), checked both ways: the page has a heading
for every code and no other, and every message an entry quotes prints its code."""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.cli.troubleshooting import ENTRIES, PAGE, code_of, error_line, quotes
from snakebot.paths import REPO_ROOT

PACKAGE = REPO_ROOT / "host" / "snakebot"
HOLE = "\x00"  # what the code fills in at run time: "..." in a quoted message


def _constants(tree: ast.Module) -> dict[str, str]:
    """The module's NAME = "text" constants, which messages put in by name."""
    found = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant):
            if isinstance(node.value.value, str):
                for target in node.targets:
                    if isinstance(target, ast.Name):
                        found[target.id] = node.value.value
    return found


def _render(node: ast.AST, names: dict[str, str]) -> str | None:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        parts = []
        for value in node.values:
            if isinstance(value, ast.Constant):
                parts.append(str(value.value))
            elif isinstance(value, ast.FormattedValue) and isinstance(value.value, ast.Name):
                parts.append(names.get(value.value.id, HOLE))
            else:
                parts.append(HOLE)
        return "".join(parts)
    return None


@cache
def messages() -> tuple[str, ...]:
    """Every string literal and f-string in the package, holes marked."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        names = _constants(tree)
        for node in ast.walk(tree):
            text = _render(node, names)
            if text is not None and len(text) > 8:
                found.append(text)
    return tuple(found)


def printed(quoted: str) -> bool:
    """Whether a message quoted with ``...`` for its variable parts is one the code has."""
    return any(quotes(quoted, text.replace(HOLE, "...")) for text in messages())


def quoted_in(page: Path, pattern: re.Pattern[str]) -> list[str]:
    return pattern.findall(page.read_text(encoding="utf-8"))


DOCS = REPO_ROOT / "docs"
ENTRY_HEADING = re.compile(r"^### (E\d{3}) `(.+)`$")
HEADING_LINES = re.findall(r"^### .*$", (REPO_ROOT / PAGE).read_text(encoding="utf-8"), re.M)
HEADINGS = [m.group(2) for line in HEADING_LINES if (m := ENTRY_HEADING.match(line))]
TABLE_ROW = re.compile(r"^\| `([^`]+)` \| [^|]+ \| [^|]+ \|$", re.M)  # message, cause, fix
FAILURES = quoted_in(DOCS / "first-flash.md", TABLE_ROW)


def test_the_pages_quote_messages():
    assert len(HEADINGS) >= 20 and len(FAILURES) >= 6


@pytest.mark.parametrize("message", HEADINGS + FAILURES)
def test_a_quoted_message_is_one_the_code_prints(message):
    assert printed(message), f"no message in host/snakebot reads {message!r}"


def test_a_reworded_message_is_caught():
    assert not printed("the bootloader sent no 'Checksum:' report after lunch")


def test_the_pages_headings_are_the_table_of_codes():
    expected = [f"### {code} `{quoted}`" for code, quoted in ENTRIES.items()]
    assert HEADING_LINES == expected, (
        "the headings of " + PAGE + " should read:\n" + "\n".join(expected)
    )


def _instances(quoted: str) -> list[str]:
    """The messages in the code that ``quoted`` quotes, their holes filled with a word."""
    found = [t for t in messages() if quotes(quoted, t.replace(HOLE, "..."))]
    return [t.replace(HOLE, "x1") for t in found]


@pytest.mark.parametrize("code", ENTRIES)
def test_every_message_an_entry_quotes_prints_its_code(code):
    instances = _instances(ENTRIES[code])
    assert instances, f"no message in host/snakebot reads {ENTRIES[code]!r}"
    for text in instances:
        assert error_line(text).startswith(f"error[{code}]: "), text  # (shortened if long)


def test_a_message_without_an_entry_prints_no_code():
    assert code_of("the frame rate must be positive") is None
    assert error_line("the frame rate must be positive") == "error: the frame rate must be positive"


@pytest.mark.parametrize(
    "args, status, code",
    [
        (["stop", "--port", "/dev/snakebot-no-such-port"], 2, "E101"),
        (["bus", "ping", "7", "--port", "sim://?ids=1"], 1, "E203"),
        (["bus", "scan", "--ids", "5", "--port", "sim://?ids=1"], 1, "E202"),
    ],
)
def test_the_cli_prints_the_code_of_a_real_error(args, status, code):
    result = CliRunner().invoke(main, args)
    assert result.exit_code == status, result.output
    line = result.stderr.strip().splitlines()[-1]  # after any progress (bus scan's)
    assert line.startswith(f"error[{code}]: "), result.stderr
    assert (REPO_ROOT / PAGE).read_text(encoding="utf-8").count(f"### {code} ") == 1


def test_the_cli_prints_the_code_of_a_refused_option(tmp_path):
    link = tmp_path / "walk.gait"
    link.symlink_to(tmp_path / "elsewhere")
    args = ["gait", "serpenoid", "snake3", "-A", "20deg", "-w", "90deg", "-d", "90deg"]
    result = CliRunner().invoke(main, [*args, "--cycles", "1", "-o", str(link)])
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith("error[E702]: Invalid value for '--output'"), result.stderr
