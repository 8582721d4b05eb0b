"""A world's history: rows of numbers, the latest ``keep`` of them in a ring buffer
allocated (and touched) once, so a server that samples for hours holds the same memory
after its first minute as after its first day; without ``keep``, every row, in an array
that doubles as it fills.

    history = History(width=3, keep=60_000)
    history.append((t, x, y))          # or history.slot()[:] = ... to fill it in place
    rows = history.array()             # oldest first, a copy
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

FIRST_CAPACITY = 256
"""Rows an unbounded history starts with (it doubles when full)."""


class History:
    """The latest ``keep`` rows of ``width`` numbers (all of them when ``keep`` is None)."""

    def __init__(self, width: int, keep: int | None = None, dtype: DTypeLike = float) -> None:
        if keep is not None and keep < 1:
            raise ValueError(f"keep must be at least 1 row, not {keep}")
        self.width = width
        self.keep = keep
        # A bounded ring is written through once here, so its pages are resident from
        # the start and the process does not grow as the ring fills.
        self._rows = np.zeros((keep or FIRST_CAPACITY, width), dtype=dtype)
        self._rows.fill(0)
        self.total = 0
        """Rows appended since the start, including those dropped."""

    def __len__(self) -> int:
        return min(self.total, len(self._rows))

    @property
    def dropped(self) -> int:
        """Rows that no longer fit, the oldest."""
        return self.total - len(self)

    def slot(self) -> np.ndarray:
        """The next row, to be filled in place (it counts as appended)."""
        rows = self._rows
        if self.keep is None and self.total == len(rows):
            self._rows = rows = np.concatenate((rows, np.zeros_like(rows)))
        row = rows[self.total % len(rows)]
        self.total += 1
        return row

    def append(self, row: ArrayLike) -> None:
        self.slot()[:] = row

    def extend(self, rows: Iterable[ArrayLike] | np.ndarray) -> None:
        block = np.asarray(rows, dtype=self._rows.dtype).reshape(-1, self.width)
        if self.keep is None:
            while self.total + len(block) > len(self._rows):
                self._rows = np.concatenate((self._rows, np.zeros_like(self._rows)))
            self._rows[self.total : self.total + len(block)] = block
            self.total += len(block)
            return
        if len(block) > self.keep:  # only the latest fit
            self.total += len(block) - self.keep
            block = block[-self.keep :]
        start = self.total % self.keep
        head = min(len(block), self.keep - start)
        self._rows[start : start + head] = block[:head]
        self._rows[: len(block) - head] = block[head:]
        self.total += len(block)

    def array(self) -> np.ndarray:
        """The rows kept, oldest first (a copy)."""
        rows, n = self._rows, len(self)
        if self.keep is None or self.total <= self.keep:
            return rows[:n].copy()
        start = self.total % self.keep
        return np.concatenate((rows[start:], rows[:start]))
