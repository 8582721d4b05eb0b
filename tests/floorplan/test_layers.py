"""The floor plan holds: every module of ``host/snakebot`` imports only from its own layer
or the layers below it, ``link`` never reaches the emulator, and no two packages import
each other, directly or round a loop.

Layers, top to bottom (README, "Layout"): ``cli``; ``plots``, which draws what
``workflows`` return; ``workflows``; ``sim`` and ``link`` side by side on ``model``; then
``formats``, ``facts`` and the package root (``errors``, ``core``, ``paths``,
``settings``, ``extras``, ``userfiles``, ``firmware``), which every layer may use.
The imports are read from the source with ``ast``: nothing is imported to check them.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from functools import cache
from pathlib import Path

import pytest

from snakebot.paths import REPO_ROOT

PACKAGE = REPO_ROOT / "host" / "snakebot"
RANK = {"root": 0, "facts": 1, "formats": 2, "model": 3, "link": 4, "sim": 4, "workflows": 5}
RANK |= {"plots": 6, "cli": 7}
"""A module may import from a layer of lower or equal rank; ``link`` and ``sim`` share a
rank but only ``sim`` may import ``link`` (as a bus master uses a port)."""
ENTRY_POINTS = {"snakebot.__main__"}
"""``python -m snakebot`` runs the CLI: the one module above it."""


def layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in RANK else "root"


def package(module: str, modules: dict[str, Path]) -> str:
    """The package a module belongs to (itself for a package's ``__init__``)."""
    path = modules[module]
    return module if path.name == "__init__.py" else module.rpartition(".")[0]


@cache
def modules() -> dict[str, Path]:
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found[name] = path
    return found


@cache
def imports() -> dict[str, set[tuple[str, int]]]:
    """module -> {(imported snakebot module, line)}; ``from p import m`` counts ``p.m``
    when ``m`` is a module, and relative imports are resolved."""
    mods = modules()
    out: dict[str, set[tuple[str, int]]] = defaultdict(set)
    for name, path in mods.items():
        here = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = here.split(".")[: len(here.split(".")) - node.level + 1]
                    base = ".".join([*anchor, *([base] if base else [])])
                targets = [base] + [f"{base}.{a.name}" for a in node.names]
            else:
                continue
            for target in targets:
                if target in mods and target.startswith("snakebot"):
                    out[name].add((target, node.lineno))
    return out


def allowed(source: str, target: str) -> bool:
    if source in ENTRY_POINTS:
        return True
    a, b = layer(source), layer(target)
    if a == "link" and b == "sim":
        return False
    return RANK[b] <= RANK[a]


def violations() -> list[str]:
    return sorted(
        f"{modules()[source].relative_to(REPO_ROOT)}:{line}: {layer(source)} imports "
        f"{target} ({layer(target)})"
        for source, targets in imports().items()
        for target, line in targets
        if not allowed(source, target)
    )


def package_cycles() -> list[list[str]]:
    """Strongly connected components of more than one package (Tarjan's algorithm)."""
    mods = modules()
    graph: dict[str, set[str]] = defaultdict(set)
    for source, targets in imports().items():
        a = package(source, mods)
        for target, _ in targets:
            b = package(target, mods)
            # a package's __init__ importing its own submodules is not a cycle
            if a != b and not b.startswith(a + "."):
                graph[a].add(b)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(set(graph) | {p for ps in graph.values() for p in ps}):
        if v not in index:
            visit(v)
    return cycles


def test_every_import_goes_down_the_layers() -> None:
    assert violations() == []


def test_no_package_imports_a_package_that_imports_it_back() -> None:
    assert package_cycles() == []


def test_every_module_is_in_a_layer_folder_or_the_root() -> None:
    root = {m for m in modules() if layer(m) == "root"}
    assert root == {
        "snakebot",
        "snakebot.__main__",
        "snakebot._core_build",
        "snakebot.core",
        "snakebot.errors",
        "snakebot.extras",
        "snakebot.firmware",
        "snakebot.paths",
        "snakebot.settings",
        "snakebot.userfiles",
    }


@pytest.mark.parametrize(
    ("source", "target", "ok"),
    [
        ("snakebot.model.plan.planner", "snakebot.sim.controller_pty", False),
        ("snakebot.link.controller.client", "snakebot.sim.serve", False),
        ("snakebot.sim.serve", "snakebot.link.transport", True),
        ("snakebot.formats.gaittable.layout", "snakebot.link.controller", False),
        ("snakebot.cli.demo", "snakebot.workflows.demo", True),
        ("snakebot.workflows.demo", "snakebot.plots.demo", False),
        ("snakebot.facts.boards", "snakebot.core", True),
    ],
)
def test_the_rule_itself(source: str, target: str, ok: bool) -> None:
    # The check would pass on any tree if `allowed` said yes to everything.
    assert allowed(source, target) is ok
