"""The same search on a Dask LocalCluster (two worker processes, loopback only) as on
this machine's process pool: the same rows, and the table resumes across the two."""

import json

import pytest
from click.testing import CliRunner

from snakebot.cli import main
from snakebot.workflows.search.results import read_results

distributed = pytest.importorskip("distributed")

GRID = (
    "--param",
    "A=10deg:70deg:4",
    "--param",
    "delta=10deg:150deg:5",
    "--param",
    "omega=360deg",
    "--robust",
    "rolling=0.01:0.1:2",
)


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    ) as c:
        yield c.scheduler_address


def search(*args):
    return CliRunner().invoke(
        main, ["gait", "search", "snake5", *map(str, args), "--json"], catch_exceptions=False
    )


def _by_key(rows):
    return {(r["amplitude"], r["delta"], r["rolling"]): r for r in rows}


def test_a_cluster_search_matches_the_local_pool_and_resumes(tmp_path, cluster):
    local, remote = tmp_path / "local.parquet", tmp_path / "remote.parquet"
    first = search(*GRID, "-o", local, "--workers", 2)
    assert first.exit_code == 0, first.output
    result = search(*GRID, "-o", remote, "--cluster", cluster)
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["workers"] == 2
    assert summary["runs_evaluated"] == 40
    mine, theirs = _by_key(read_results(local)), _by_key(read_results(remote))
    assert mine.keys() == theirs.keys() and len(mine) == 40
    for key, row in mine.items():
        other = theirs[key]
        assert row["status"] == other["status"] and row["reason"] == other["reason"]
        assert row["dx"] == other["dx"] or (row["status"] == "failed")
    assert sum(r["status"] == "failed" for r in mine.values()) == 10  # A = 70 deg
    assert json.loads(first.stdout)["best"] == summary["best"]
    # what the pool ran, the cluster does not run again
    again = json.loads(search(*GRID, "-o", local, "--cluster", cluster).stdout)
    assert (again["runs_evaluated"], again["runs_reused"]) == (0, 40)
