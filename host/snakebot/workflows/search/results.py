"""The results table: one row per run, as Parquet (pyarrow) or CSV, read back so a
re-run skips the runs already done.

Every row carries the search's settings (robot, world, cycles, rate), the run's gait
and robustness parameters, its status and reason, and the metrics. The file is rewritten
whole through a temporary file and a rename, so an interrupted search leaves either the
previous or the new table, never half of one.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

from snakebot.userfiles import UnreadableInput, read_bounded, staged_output
from snakebot.workflows.search.evaluate import METRICS, Settings
from snakebot.workflows.search.space import GAIT_PARAMETERS, ROBUST_PARAMETERS, SearchError

SETTINGS_COLUMNS = tuple(f.name for f in fields(Settings))
TEXT_COLUMNS = ("robot", "world", "status", "reason")
COLUMNS = (
    *SETTINGS_COLUMNS,
    *GAIT_PARAMETERS,
    *ROBUST_PARAMETERS,
    "status",
    "reason",
    *METRICS,
)
FORMATS = (".parquet", ".csv")
KEY_DIGITS = 12
"""Significant digits that identify a run's parameters when a table is read back."""


def check_path(path: Path) -> Path:
    if path.suffix.lower() not in FORMATS:
        raise SearchError(
            f"-o {path}: the results table must end in .parquet or .csv, not {path.suffix!r}"
        )
    return path


def run_key(point: dict[str, Any]) -> tuple[float | None, ...]:
    """What identifies a run within a search: its parameters, rounded (None: unused)."""
    return tuple(_rounded(point.get(n)) for n in (*GAIT_PARAMETERS, *ROBUST_PARAMETERS))


def _rounded(value: Any) -> float | None:
    if value is None or value == "" or math.isnan(float(value)):
        return None
    return float(f"{float(value):.{KEY_DIGITS}g}")


def settings_row(settings: Settings) -> dict[str, Any]:
    return asdict(settings)


def _complete(row: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for c in COLUMNS:
        value = row.get(c)
        out[c] = (
            ("" if value is None else str(value))
            if c in TEXT_COLUMNS
            else (math.nan if value is None or value == "" else float(value))
        )
    return out


def write_results(path: Path, rows: Iterable[dict[str, Any]]) -> None:
    """Write every row (all COLUMNS; a missing value is NaN) atomically."""
    table = [_complete(r) for r in rows]
    with staged_output(path) as tmp:
        if path.suffix.lower() == ".parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            columns = {c: [r[c] for r in table] for c in COLUMNS}
            schema = pa.schema(
                [(c, pa.string() if c in TEXT_COLUMNS else pa.float64()) for c in COLUMNS]
            )
            pq.write_table(pa.table(columns, schema=schema), tmp)
        else:
            with open(tmp, "w", newline="") as fh:
                writer = csv.DictWriter(fh, fieldnames=COLUMNS)
                writer.writeheader()
                writer.writerows({c: _csv(r[c]) for c in COLUMNS} for r in table)


def _csv(value: Any) -> Any:
    return repr(value) if isinstance(value, float) else value


MAX_RESULTS_BYTES = 256 << 20
"""The largest results table resumed from: the most runs a search may have
(``space.MAX_RUNS``) at a few hundred bytes a row."""


def read_results(path: Path) -> list[dict[str, Any]]:
    """The rows of an existing table ([] if there is none)."""
    if not path.exists():
        return []
    try:
        data = read_bounded(path, MAX_RESULTS_BYTES, "search results table")
        if path.suffix.lower() == ".parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            rows = pq.read_table(pa.BufferReader(data)).to_pylist()
        else:
            rows = list(csv.DictReader(io.StringIO(data.decode("utf-8"), newline="")))
        missing = [c for c in COLUMNS if rows and c not in rows[0]]
        if missing:
            raise ValueError(f"no column {missing[0]!r}")
        return [_complete(r) for r in rows]
    except (ValueError, OSError, KeyError, UnreadableInput) as exc:
        raise SearchError(
            f"cannot resume from {path}: it is not a search results table ({exc}); "
            "choose another -o or remove it"
        ) from None
    except Exception as exc:  # pyarrow's own errors: a file that is not Parquet
        raise SearchError(
            f"cannot resume from {path}: it is not a search results table ({exc}); "
            "choose another -o or remove it"
        ) from None


def finished_runs(
    rows: list[dict[str, Any]], settings: Settings, path: Path
) -> dict[tuple[float | None, ...], dict[str, Any]]:
    """The runs of ``rows`` by key; SearchError if they are another search's."""
    want = _complete(settings_row(settings))
    done = {}
    for row in rows:
        if any(row[c] != want[c] for c in SETTINGS_COLUMNS):
            got = ", ".join(f"{c} {row[c]}" for c in SETTINGS_COLUMNS)
            raise SearchError(
                f"{path} holds another search ({got}): choose another -o or remove it"
            )
        done[run_key(row)] = row
    return done
