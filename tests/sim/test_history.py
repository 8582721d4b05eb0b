"""A world's history keeps the latest rows in a ring allocated once (so a server's memory
stays flat), oldest first when read, or every row when unbounded."""

from __future__ import annotations

import numpy as np
import pytest

from snakebot.sim.history import FIRST_CAPACITY, History


def rows(first: int, count: int) -> np.ndarray:
    return np.arange(first, first + count, dtype=float)[:, None] * [1.0, -1.0]


def test_a_bounded_history_keeps_the_latest_rows_oldest_first():
    history = History(2, keep=5)
    for k in range(12):
        history.append((k, -k))
    assert np.array_equal(history.array(), rows(7, 5))
    assert (len(history), history.total, history.dropped) == (5, 12, 7)


@pytest.mark.parametrize("blocks", [[3, 4, 2], [7], [2, 11, 1], [5, 5, 5]])
def test_blocks_wrap_around_the_ring_as_rows_one_at_a_time_would(blocks):
    history, one_by_one = History(2, keep=5), History(2, keep=5)
    first = 0
    for size in blocks:
        history.extend(rows(first, size))
        for row in rows(first, size):
            one_by_one.slot()[:] = row
        first += size
    assert np.array_equal(history.array(), one_by_one.array())
    assert np.array_equal(history.array(), rows(first - min(first, 5), min(first, 5)))
    assert history.total == first


def test_the_ring_is_allocated_once_however_many_rows_come():
    history = History(48, keep=1000)
    held = history._rows
    for k in range(5000):
        history.slot()[0] = k
    assert history._rows is held and held.shape == (1000, 48)
    assert history.array()[-1, 0] == 4999


def test_an_unbounded_history_keeps_every_row():
    history = History(2)
    history.extend(rows(0, FIRST_CAPACITY - 1))
    for row in rows(FIRST_CAPACITY - 1, 3 * FIRST_CAPACITY):
        history.append(row)
    history.extend(rows(4 * FIRST_CAPACITY - 1, 2 * FIRST_CAPACITY))
    assert np.array_equal(history.array(), rows(0, 6 * FIRST_CAPACITY - 1))
    assert history.dropped == 0
