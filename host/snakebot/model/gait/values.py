"""Parsing what users type: angles and rates with optional ``deg`` suffixes, lists of
them, and linear combinations of vector fields such as ``2*g1-h3`` or ``(2*g1-h3)/2``.

Only arithmetic on numbers and ``pi`` is accepted (parsed with ``ast``, never ``eval``).
"""

from __future__ import annotations

import ast
import math
import re

from snakebot.errors import InputError, quoted

_SUFFIX = re.compile(r"^(?P<body>.*?)\s*(?P<unit>deg|°|rad)?$", re.S)
_CONSTANTS = {"pi": math.pi, "tau": math.tau}
_FIELD = re.compile(r"^[gh][1-9]$")
MAX_EXPRESSION = 500
"""The longest expression read, in characters: enough for any number or combination of
fields, and short enough that parsing and evaluating it stays shallow and quick (a
10,000-term sum would pass Python's recursion limit, a long run of names exhausts the
parser's memory)."""


class ExpressionError(InputError):
    """A value (an angle, a rate, a field expression) that cannot be understood."""


def _number(node: ast.AST, text: str) -> float:
    if (
        isinstance(node, ast.Constant)
        and isinstance(node.value, int | float)
        and not isinstance(node.value, bool)
    ):
        return float(node.value)
    if isinstance(node, ast.Name) and node.id in _CONSTANTS:
        return _CONSTANTS[node.id]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        value = _number(node.operand, text)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.BinOp) and isinstance(
        node.op, ast.Add | ast.Sub | ast.Mult | ast.Div | ast.Pow
    ):
        a, b = _number(node.left, text), _number(node.right, text)
        try:
            if isinstance(node.op, ast.Add):
                return a + b
            if isinstance(node.op, ast.Sub):
                return a - b
            if isinstance(node.op, ast.Mult):
                return a * b
            if isinstance(node.op, ast.Div):
                return a / b
            power = a**b
        except (ZeroDivisionError, OverflowError) as exc:
            raise ExpressionError(f"cannot compute {quoted(text)} ({exc})") from None
        if isinstance(power, complex):  # a negative number to a fractional power
            raise ExpressionError(
                f"{quoted(text)} is not a real number (a negative base to a fractional power)"
            )
        return power
    raise ExpressionError(
        f"cannot read {quoted(text)}: use a number, pi, + - * / and an optional "
        "'deg' suffix (e.g. 0.5, pi/3, -60deg)"
    )


def _parsed(text: str, what: str, example: str) -> ast.expr:
    """The expression ``text`` as a tree (ExpressionError naming ``what`` and ``example``
    if it cannot be read or is longer than MAX_EXPRESSION)."""
    if len(text) > MAX_EXPRESSION:
        raise ExpressionError(
            f"{what} {quoted(text)} is longer than {MAX_EXPRESSION} characters: write e.g. "
            f"{example}"
        )
    try:
        return ast.parse(text.strip(), mode="eval").body
    except (SyntaxError, ValueError, MemoryError, RecursionError):
        raise ExpressionError(f"cannot read {what} {quoted(text)}: write e.g. {example}") from None


def parse_number(text: str) -> float:
    """A plain arithmetic expression over numbers and pi."""
    tree = _parsed(text, "the number", "0.5 or pi/3")
    value = _number(tree, text)
    if not math.isfinite(value):
        raise ExpressionError(f"{quoted(text)} is not a finite number")
    return value


def parse_angle(text: str) -> float:
    """Radians from ``"0.5"``, ``"pi/3"``, ``"30deg"``, ``"-60 deg"`` or ``"1rad"``.
    The same works for rates: ``"90deg"`` is 90 degrees per second, in rad/s."""
    m = _SUFFIX.match(text.strip())
    assert m is not None
    value = parse_number(m.group("body"))
    return math.radians(value) if m.group("unit") in ("deg", "°") else value


def parse_angles(text: str, count: int | None = None, what: str = "values") -> list[float]:
    """A comma-separated list of angles (each as parse_angle), optionally of fixed length."""
    parts = [p for p in text.split(",")]
    if any(not p.strip() for p in parts):
        raise ExpressionError(
            f"{what} {quoted(text)} has an empty entry: separate values with commas"
        )
    values = [parse_angle(p) for p in parts]
    if count is not None and len(values) != count:
        raise ExpressionError(
            f"{what} needs {count} comma-separated values, got {len(values)} in {quoted(text)}"
        )
    return values


def _combination(node: ast.AST, text: str) -> dict[str, float]:
    """A linear combination as {field name: coefficient}; the key "" holds a constant."""
    if isinstance(node, ast.Name) and _FIELD.match(node.id):
        return {node.id: 1.0}
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        inner = _combination(node.operand, text)
        sign = -1.0 if isinstance(node.op, ast.USub) else 1.0
        return {k: sign * v for k, v in inner.items()}
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add | ast.Sub):
        a, b = _combination(node.left, text), _combination(node.right, text)
        sign = 1.0 if isinstance(node.op, ast.Add) else -1.0
        out = dict(a)
        for k, v in b.items():
            out[k] = out.get(k, 0.0) + sign * v
        return out
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult | ast.Div):
        a, b = _combination(node.left, text), _combination(node.right, text)
        a_const, b_const = set(a) <= {""}, set(b) <= {""}
        if isinstance(node.op, ast.Div):
            if not b_const or b.get("", 0.0) == 0.0:
                raise ExpressionError(f"in {quoted(text)}: divide only by a non-zero number")
            return {k: v / b[""] for k, v in a.items()}
        if not (a_const or b_const):
            raise ExpressionError(
                f"in {quoted(text)}: fields can only be scaled by numbers, not multiplied together"
            )
        scale, combo = (a.get("", 0.0), b) if a_const else (b.get("", 0.0), a)
        return {k: scale * v for k, v in combo.items()}
    try:
        return {"": _number(node, text)}
    except ExpressionError:
        raise ExpressionError(
            f"cannot read field expression {quoted(text)}: write a combination of "
            "fields like g1, 2*g1-h3 or (2*g1-h3)/2"
        ) from None


def parse_field_expression(text: str, names: tuple[str, ...]) -> dict[str, float]:
    """``{name: coefficient}`` (non-zero only) for a combination of the given field names."""
    combo = _combination(_parsed(text, "the field expression", "2*g1-h3"), text)
    if combo.get("", 0.0) != 0.0:
        raise ExpressionError(
            f"{quoted(text)} adds a plain number to fields: write only fields and their multiples"
        )
    combo.pop("", None)
    unknown = sorted(set(combo) - set(names))
    if unknown:
        raise ExpressionError(
            f"{quoted(text)} uses {', '.join(unknown)}, which this robot does not have: "
            f"use {', '.join(names)}"
        )
    combo = {k: v for k, v in combo.items() if v != 0.0}
    if not combo:
        raise ExpressionError(f"{quoted(text)} is the zero field: nothing to follow")
    return {n: combo[n] for n in names if n in combo}
