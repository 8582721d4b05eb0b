"""How deeply a TOML or JSON text nests its arrays and tables, found in one pass before
any parser sees it: Python's parsers recurse once per level, and a file nested 5,000
deep ends in a RecursionError (or worse) instead of a message."""

from __future__ import annotations

MAX_NESTING = 64
"""The deepest nesting of arrays and tables read from a user's file; snakebot's own
formats nest four levels at most."""

_OPEN = frozenset("[{")
_CLOSE = frozenset("]}")


def nesting_depth(text: str, comments: bool = True) -> int:
    """The deepest nesting of ``[``/``{`` in ``text``, not counting brackets inside
    strings (``"..."``, ``'...'``, and TOML's triple-quoted forms) or, with
    ``comments``, after a ``#`` that starts a TOML comment. A rough but safe upper
    bound: it never reports less than a parser would reach."""
    depth = deepest = 0
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c in _OPEN:
            depth += 1
            deepest = max(deepest, depth)
        elif c in _CLOSE:
            depth = max(0, depth - 1)
        elif c == "#" and comments:
            end = text.find("\n", i)
            i = n if end < 0 else end
            continue
        elif c in "\"'":
            quote = c * 3 if text.startswith(c * 3, i) else c
            i += len(quote)
            while i < n and not text.startswith(quote, i):
                if c == '"' and text[i] == "\\":
                    i += 1
                elif len(quote) == 1 and text[i] == "\n":
                    break  # an unterminated string: the parser will say so
                i += 1
            i += len(quote)
            continue
        i += 1
    return deepest


def too_deep(text: str, comments: bool = True) -> str | None:
    """A sentence saying ``text`` nests too deeply (to follow the file's name), or None."""
    depth = nesting_depth(text, comments)
    if depth > MAX_NESTING:
        return (
            f"nests arrays or tables {depth} deep, more than the {MAX_NESTING} any snakebot "
            "file needs: check that it is the right file"
        )
    return None
