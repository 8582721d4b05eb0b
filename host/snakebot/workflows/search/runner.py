"""Where the runs happen: a process pool on this machine, or a Dask distributed
scheduler. Both take batches of runs and hand back each batch's rows as it finishes."""

from __future__ import annotations

import os
import pickle
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, Protocol

from snakebot.workflows.search.evaluate import Settings, evaluate_many
from snakebot.workflows.search.space import SearchError

Rows = list[dict[str, Any]]
Batch = list[dict[str, float]]
CONNECT_TIMEOUT_S = 5.0


class Runner(Protocol):
    """Runs batches of points; yields (batch index, rows) as batches finish.
    ``batch_s``: the least work (s) worth handing over as one batch, what a batch's
    dispatch costs considered."""

    workers: int
    batch_s: float

    def run(self, settings: Settings, batches: list[Batch]) -> Iterator[tuple[int, Rows]]: ...

    def close(self) -> None: ...


class InlineRunner:
    """Everything in this process (one worker: no start-up cost, easiest to debug)."""

    workers = 1
    batch_s = 0.1  # only for progress: nothing is handed over

    def run(self, settings: Settings, batches: list[Batch]) -> Iterator[tuple[int, Rows]]:
        for i, batch in enumerate(batches):
            yield i, evaluate_many(settings, batch)

    def close(self) -> None:
        pass


class LocalRunner:
    """A pool of ``workers`` processes on this machine (default: one per core)."""

    batch_s = 0.1  # a pool's hand-over (pickles through a pipe) takes well under 1 ms

    def __init__(self, workers: int | None = None) -> None:
        self.workers = workers or os.cpu_count() or 1
        self._pool = ProcessPoolExecutor(self.workers)

    def run(self, settings: Settings, batches: list[Batch]) -> Iterator[tuple[int, Rows]]:
        futures = {self._pool.submit(evaluate_many, settings, b): i for i, b in enumerate(batches)}
        try:
            for future in as_completed(futures):
                yield futures[future], future.result()
        finally:
            for future in futures:
                future.cancel()

    def close(self) -> None:
        self._pool.shutdown(cancel_futures=True)


def evaluate_packed(settings: Settings, batch: bytes) -> bytes:
    """:func:`evaluate_many` on a pickled batch, its rows pickled: what a Dask task
    carries is then one opaque value, which Dask neither walks nor converts."""
    return pickle.dumps(evaluate_many(settings, pickle.loads(batch)))


class DaskRunner:
    """The same runs on a Dask distributed scheduler (``tcp://HOST:8786``); its workers
    need snakebot installed.

    A task costs the scheduler and this client milliseconds of CPU, mostly whatever it
    carries (measured on a loaded two-core LocalCluster: 6-7 ms for a no-op task, 9 ms
    with a batch of 50 points and its rows), and a worker waits a round trip for its
    next one: so no batch holds less than 0.25 s of work (the local pool's: 0.1 s).
    Each batch goes, and its rows come back, pickled (:func:`evaluate_packed`): Dask
    walks a task's arguments for futures it may hold, 20,000 calls for the batches of a
    4,000-run search, and the client's CPU for such a search fell from 0.42 s to 0.29 s
    (the pool's client: 0.08 s), CPU the workers share on a machine with as many cores."""

    batch_s = 0.25

    def __init__(self, address: str) -> None:
        try:
            from distributed import Client
        except ImportError:
            raise SearchError(
                "a search on a cluster needs Dask: pip install 'snakebot[search]'"
            ).about("cluster") from None
        try:
            self._client = Client(address, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            raise SearchError(
                f"cannot reach the Dask scheduler at {address} ({exc}): start one with "
                "`dask scheduler` and workers with `dask worker ADDRESS`, or search on this "
                "machine"
            ).about("cluster") from None
        self.workers = max(1, sum(self._client.nthreads().values()))

    def run(self, settings: Settings, batches: list[Batch]) -> Iterator[tuple[int, Rows]]:
        from distributed import as_completed as dask_completed

        futures = [
            self._client.submit(evaluate_packed, settings, pickle.dumps(b), pure=False)
            for b in batches
        ]
        index = {f.key: i for i, f in enumerate(futures)}
        try:
            for future in dask_completed(futures):
                yield index[future.key], pickle.loads(future.result())
        finally:
            self._client.cancel(futures)

    def close(self) -> None:
        self._client.close()


MAX_WORKERS = 64
"""The most worker processes on this machine: each holds a Python with its world (about
100 MB with MuJoCo), so 100,000 of them would take the machine."""


def make_runner(workers: int | None, cluster: str | None) -> Runner:
    """The runner asked for: a Dask client, this process (``workers == 1``) or a pool."""
    if cluster:
        return DaskRunner(cluster)
    if workers == 1:
        return InlineRunner()
    return LocalRunner(workers)


LONGEST_BATCH_S = 1.0
"""The most work one batch holds: progress, the checkpoint (every two seconds) and a stop
come between batches, so a search of minutes still reports and saves every second or
so (one worker's first batch of a 90,000-run grid was 22 s of work)."""


def batches_of(points: Batch, runner: Runner, per_run_s: float) -> list[Batch]:
    """Split ``points`` into batches, handed out in order, each a (2 w)-th of the points
    left (w workers: guided self-scheduling), so the first are large (few hand-overs) and
    the last small (the workers finish together); none smaller than ``runner.batch_s``
    of work (a hand-over's cost) nor larger than a (4 w)-th of all (every worker gets
    several, for balance and progress) or :data:`LONGEST_BATCH_S` of work."""
    least = max(1, int(runner.batch_s / per_run_s))
    most = max(1, min(len(points) // (4 * runner.workers), int(LONGEST_BATCH_S / per_run_s)))
    out, start = [], 0
    while start < len(points):
        left = len(points) - start
        size = min(most, max(least, -(-left // (2 * runner.workers))))
        out.append(points[start : start + size])
        start += size
    return out


ProgressFn = Callable[[int], None]
