"""What the commands print: JSON that is always valid, written one way everywhere.

``json.dumps`` writes ``NaN`` and ``Infinity`` for non-finite floats, which no JSON
parser accepts; every ``--json`` goes through :func:`dumps`, where they become ``null``
(the value is unknown or unbounded, which is what ``null`` says). numpy scalars and
arrays are written as the numbers they hold.
"""

from __future__ import annotations

import json
import math
from typing import Any

import click
import numpy as np


def jsonable(value: Any) -> Any:
    """``value`` with non-finite floats replaced by None and numpy values made plain."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, np.generic):
        return jsonable(value.item())
    return value


def dumps(value: Any, **kwargs: Any) -> str:
    """JSON text for ``value``; never ``NaN`` or ``Infinity`` (see :func:`jsonable`)."""
    return json.dumps(jsonable(value), allow_nan=False, **kwargs)


def echo_json(as_json: bool, value: Any, **kwargs: Any) -> bool:
    """With --json, print ``value`` as JSON (:func:`dumps`, ``kwargs`` as its) and say so;
    without, print nothing: the command prints its text instead."""
    if as_json:
        click.echo(dumps(value, **kwargs))
    return as_json
