"""Every repository path and every ``python -m MODULE`` the documents name is real.

The documents are ``README.md`` and every Markdown file under ``docs/`` (the history
included), plus the other Markdown pages a reader is sent to (``protocol/``,
``fuzz/README.md``). A path is a word that starts with one of the repository's top
folders (``tests/``, ``host/``, ``bench/``, ``tools/``, ``firmware/``, ``docs/``,
``protocol/``, ``fuzz/``); one with a ``*`` or ``[ch]`` in it must match at least one
file. A module is what
follows ``python -m``; ``importlib.util.find_spec`` must find it from the repository
root, as the command would run there (a package must have a ``__main__``).
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest

from snakebot.paths import REPO_ROOT

TOP_FOLDERS = ("tests", "host", "bench", "tools", "firmware", "docs", "protocol", "fuzz")
PATH = re.compile(r"(?<![\w./~$-])((?:" + "|".join(TOP_FOLDERS) + r")/[\w./*+\[\]-]*)")
MODULE = re.compile(r"\bpython3? -m ([A-Za-z_][\w.]*)")


def documents() -> list[Path]:
    pages = [REPO_ROOT / "README.md", *sorted((REPO_ROOT / "docs").rglob("*.md"))]
    pages += sorted((REPO_ROOT / "protocol").rglob("*.md"))
    pages.append(REPO_ROOT / "fuzz" / "README.md")
    return [p for p in pages if p.is_file()]


def mentions(pattern: re.Pattern[str]) -> list[tuple[str, int, str]]:
    """(document, line, the matched group) for every match in every document."""
    found = []
    for page in documents():
        name = page.relative_to(REPO_ROOT).as_posix()
        for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
            for m in pattern.finditer(line):
                found.append((name, number, m.group(1)))
    return found


def exists(path: str) -> bool:
    path = path.rstrip(".,:;-")
    if "*" in path or "[" in path:
        return any(REPO_ROOT.glob(path))
    return (REPO_ROOT / path).exists()


def test_the_documents_are_found():
    names = {p.relative_to(REPO_ROOT).as_posix() for p in documents()}
    assert {"README.md", "docs/reliability.md", "docs/hardware.md"} <= names
    assert any(n.startswith("docs/history/") for n in names)
    assert len(mentions(PATH)) > 100 and len(mentions(MODULE)) > 5  # the patterns work


def test_every_repository_path_in_the_documents_exists():
    stale = [f"{doc}:{line}: {path}" for doc, line, path in mentions(PATH) if not exists(path)]
    assert not stale, "paths that do not exist:\n" + "\n".join(stale)


def runnable(module: str) -> bool:
    """``python -m module`` finds something to run: a module, or a package with a
    ``__main__`` (a folder without one, such as an output folder that shadows a package,
    is not)."""
    try:
        spec = importlib.util.find_spec(module)
        if spec is not None and spec.submodule_search_locations is not None:
            spec = importlib.util.find_spec(f"{module}.__main__")
    except ModuleNotFoundError:  # a parent package is missing
        return False
    return spec is not None


@pytest.fixture
def from_the_repository_root(monkeypatch: pytest.MonkeyPatch) -> None:
    """``python -m`` run in the repository root has it first on ``sys.path``; so does
    the search here (with ``host`` for a checkout that is not installed)."""
    monkeypatch.chdir(REPO_ROOT)
    monkeypatch.setattr(sys, "path", [str(REPO_ROOT), str(REPO_ROOT / "host"), *sys.path])


def test_every_python_m_module_in_the_documents_is_found(from_the_repository_root: None):
    missing = []
    for doc, line, module in mentions(MODULE):
        module = module.rstrip(".")
        if not runnable(module):
            missing.append(f"{doc}:{line}: python -m {module}")
    assert not missing, "modules that cannot be found:\n" + "\n".join(missing)
