"""The error messages the documents quote are the ones the code prints: every heading of
docs/troubleshooting.md and every message in the failure table of docs/first-flash.md
is found among the messages in host/snakebot (``...`` standing for what the code fills
in), so a reworded message cannot leave its entry behind."""

from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

import pytest

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
    pattern = re.compile(".*?".join(re.escape(f) for f in quoted.split("...")))
    return any(pattern.search(text.replace(HOLE, "...")) for text in messages())


def quoted_in(page: Path, pattern: re.Pattern[str]) -> list[str]:
    return pattern.findall(page.read_text(encoding="utf-8"))


DOCS = REPO_ROOT / "docs"
HEADINGS = quoted_in(DOCS / "troubleshooting.md", re.compile(r"^### `(.+)`$", re.M))
TABLE_ROW = re.compile(r"^\| `([^`]+)` \| [^|]+ \| [^|]+ \|$", re.M)  # message, cause, fix
FAILURES = quoted_in(DOCS / "first-flash.md", TABLE_ROW)


def test_the_pages_quote_messages():
    assert len(HEADINGS) >= 20 and len(FAILURES) >= 6


@pytest.mark.parametrize("message", HEADINGS + FAILURES)
def test_a_quoted_message_is_one_the_code_prints(message):
    assert printed(message), f"no message in host/snakebot reads {message!r}"


def test_a_reworded_message_is_caught():
    assert not printed("the bootloader sent no 'Checksum:' report after lunch")
