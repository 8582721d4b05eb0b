"""Errors by class, not by list: every error of ``host/snakebot`` is bad input
(``InputError``, exit 2) or a runtime failure (``RuntimeFailure``, exit 1), never both.
An area's own base that spans both kinds (``ProtocolError``, ``ControllerError``) is
allowed only as a base: it has subclasses and nothing constructs it, so whatever is
raised has one kind. Every module is imported to find the classes; the constructions are
read from the source with ``ast``."""

from __future__ import annotations

import ast
import importlib
import pkgutil
from functools import cache

import snakebot
from snakebot.errors import InputError, RuntimeFailure, SnakebotError
from snakebot.paths import REPO_ROOT

PACKAGE = REPO_ROOT / "host" / "snakebot"
KINDS = (InputError, RuntimeFailure)


@cache
def error_classes() -> tuple[type[SnakebotError], ...]:
    """Every subclass of SnakebotError defined in the package (all modules imported)."""
    for info in pkgutil.walk_packages(snakebot.__path__, "snakebot."):
        if not info.name.endswith("__main__"):
            importlib.import_module(info.name)
    found: set[type[SnakebotError]] = set()
    todo = [SnakebotError]
    while todo:
        for sub in todo.pop().__subclasses__():
            if sub.__module__.startswith("snakebot.") and sub not in found:
                found.add(sub)
                todo.append(sub)
    return tuple(sorted(found - set(KINDS), key=lambda c: f"{c.__module__}.{c.__qualname__}"))


@cache
def constructed() -> dict[str, list[str]]:
    """Class-like names called anywhere in the package -> where (``path:line``)."""
    calls: dict[str, list[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Call):
                func = node.func
                name = func.id if isinstance(func, ast.Name) else getattr(func, "attr", "")
                where = f"{path.relative_to(REPO_ROOT)}:{node.lineno}"
                calls.setdefault(name, []).append(where)
    return calls


def kinds(cls: type) -> list[str]:
    return [k.__name__ for k in KINDS if issubclass(cls, k)]


def test_the_walk_finds_the_package_errors():
    names = {c.__name__ for c in error_classes()}
    assert {"DxlTimeout", "GaitTableError", "UploadRefused", "UploadFailed"} <= names
    assert len(names) >= 50


def kind_problem(cls: type[SnakebotError]) -> str | None:
    """Why ``cls`` breaks the rule (None: it keeps it)."""
    found = kinds(cls)
    if len(found) > 1:
        return f"{cls.__qualname__} is both {found[0]} and {found[1]}: pick one"
    if found:
        return None
    # an area base: only a base, every subclass has its kind, and nobody raises it
    subs = cls.__subclasses__()
    if not subs:
        return f"{cls.__qualname__} is neither InputError nor RuntimeFailure: derive it from one"
    if not all(len(kinds(s)) == 1 or s.__subclasses__() for s in subs):
        return f"{cls.__qualname__} has a subclass of no kind or both"
    raised = constructed().get(cls.__name__, [])
    if raised:
        return (
            f"{cls.__qualname__} spans both kinds but is constructed at {', '.join(raised)}: "
            "raise one of its subclasses"
        )
    return None


def test_every_error_is_bad_input_or_a_runtime_failure():
    # one test over every class, found at run time: importing the whole package to
    # parametrize would cost each collection of the suite a second
    problems = [p for cls in error_classes() if (p := kind_problem(cls)) is not None]
    assert not problems, "\n".join(problems)


def test_the_rule_catches_a_class_of_both_kinds_and_one_of_none():
    class Both(InputError, RuntimeFailure):
        pass

    class Neither(SnakebotError):
        pass

    assert "pick one" in (kind_problem(Both) or "")
    assert "derive it from one" in (kind_problem(Neither) or "")


def test_nothing_raises_the_root_itself():
    assert not constructed().get("SnakebotError"), "raise an InputError or a RuntimeFailure"
