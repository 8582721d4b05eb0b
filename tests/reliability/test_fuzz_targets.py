"""The libFuzzer targets (fuzz/): every saved regression input and every corpus input
replays cleanly, and a short fuzzing pass of each target finds nothing.

The pass lasts FUZZ_SECONDS per target (60 unless the environment says otherwise;
`make test` sets TEST_FUZZ_SECONDS, 20, a smoke pass within its time budget, and
`make fuzz` is the longer pass). It builds with clang's -fsanitize=fuzzer,address,undefined, which
`make setup` installs (clang and libclang-rt-14-dev; zlib1g-dev for the PC-link target's
CRC-32); without clang these tests are skipped, saying so. A failure prints the fuzzer's
log and where the failing input is.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import pytest

from snakebot.paths import REPO_ROOT

FUZZ = REPO_ROOT / "fuzz"
BUILD = REPO_ROOT / "build" / "fuzz"
TARGETS = ("fuzz_dxl_parser", "fuzz_pclink")
SECONDS = int(os.environ.get("FUZZ_SECONDS", "60"))

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        shutil.which("clang") is None,
        reason="clang not installed: `make setup` installs clang and libclang-rt-14-dev",
    ),
]


def make(*args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["make", "--no-print-directory", "-C", str(FUZZ), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )


@pytest.fixture(scope="module", autouse=True)
def built() -> None:
    done = make("all")
    assert done.returncode == 0, f"building the fuzz targets failed:\n{done.stdout}\n{done.stderr}"


@pytest.mark.parametrize("target", TARGETS)
def test_regressions_and_corpus_replay_cleanly(target: str):
    inputs = sorted(
        p
        for d in (FUZZ / "regressions" / target, FUZZ / "corpus" / target)
        if d.is_dir()
        for p in d.iterdir()
        if p.is_file()
    )
    assert inputs, f"no inputs for {target}: run `make -C fuzz seeds`"
    done = subprocess.run(
        [str(BUILD / target), "-timeout=10", *map(str, inputs)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, f"{target} fails on a saved input:\n{done.stderr[-4000:]}"
    assert done.stderr.count("Executed ") == len(inputs)


def test_the_fixed_bugs_stay_in_the_regressions():
    saved = {p.name for p in (FUZZ / "regressions" / "fuzz_pclink").iterdir()}
    assert {"roster-shrinks-mid-read", "roster-id-changes-mid-read"} <= saved


@pytest.mark.parametrize("target", TARGETS)
def test_a_short_fuzzing_pass_finds_nothing(target: str, tmp_path):
    # from the committed inputs, not what earlier passes on this machine found
    found = tmp_path / "found"
    # libFuzzer reads the committed corpus before its clock starts; at a low priority
    # beside two busy processes that alone took over two minutes
    done = make(
        f"run-{target}", f"FUZZ_SECONDS={SECONDS}", f"FUZZ_FOUND={found}", timeout=SECONDS * 3 + 600
    )
    summary = BUILD / f"{target}.json"
    assert done.returncode == 0, f"{done.stdout[-6000:]}\n{done.stderr[-2000:]}"
    stats = json.loads(summary.read_text())
    assert stats["ok"] and stats["runs"] > 0, stats
    print(done.stdout.strip().splitlines()[-1])
