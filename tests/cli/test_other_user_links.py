"""A second local user against a server's ``--link`` and ``--unix`` paths (issue #28).

In a directory both users can write, the other user (``nobody``, a real other uid) plants
what a server would take for its own: a symlink at the link path aimed at a file of ours,
a link where a killed server of ours left one, a claim directory with a forged record.
Each start is refused (exit 2, one line), and nothing planted, nor the file it points
at, is touched."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner
from other_user import as_other_user, needs_root, other_uid

from snakebot.cli import main
from snakebot.rundir import RUNTIME_ENV
from snakebot.sim.transports.claim import CLAIM_DIR_NAME

PRECIOUS = b"the victim's data\n"
SERVERS = {
    "sim bus --link": ["sim", "bus", "--ids", "1", "--link"],
    "sim bus --unix": ["sim", "bus", "--ids", "1", "--unix"],
    "sim bootloader --link": ["sim", "bootloader", "--link"],
}

pytestmark = needs_root


@pytest.fixture
def shared(shared_tmp: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """``shared_tmp`` as this process's temporary directory, where the claim records go
    when no ``XDG_RUNTIME_DIR`` is set (as on a machine without a login manager)."""
    monkeypatch.delenv(RUNTIME_ENV, raising=False)
    monkeypatch.setattr(tempfile, "tempdir", str(shared_tmp))
    yield shared_tmp


@pytest.fixture
def ours(shared: Path) -> Path:
    path = shared / "ours.txt"
    path.write_bytes(PRECIOUS)
    path.chmod(0o600)
    return path


def _refused(args: list[str], *words: str) -> str:
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    line = result.stderr.strip()
    assert line.startswith("error: ") and "\n" not in line, line
    for word in words:
        assert word in line, line
    return line


def _snapshot(path: Path) -> tuple[int, int, int, str]:
    info = os.lstat(path)
    return (info.st_ino, info.st_uid, info.st_mtime_ns, os.readlink(path))


@pytest.mark.parametrize("server", SERVERS)
def test_a_link_planted_at_the_path_to_a_file_of_ours_is_refused(shared, ours, server):
    path = shared / "ttyDXL"
    as_other_user(f"ln -s {ours} {path}")
    before = _snapshot(path)
    option = SERVERS[server][-1]
    _refused([*SERVERS[server], str(path)], f"{option}: {path} is a symlink to {ours}", "which no")
    assert _snapshot(path) == before
    assert ours.read_bytes() == PRECIOUS and ours.stat().st_uid == 0


def test_a_link_that_looks_left_by_a_dead_server_is_refused(shared):
    # A pty link such as a killed server leaves, but no record of ours names it.
    path = shared / "ttyDXL"
    as_other_user(f"ln -s /dev/pts/999999 {path}")
    before = _snapshot(path)
    _refused([*SERVERS["sim bus --link"], str(path)], "which no snakebot server made")
    assert _snapshot(path) == before


def test_a_claim_directory_with_a_forged_record_is_refused(shared):
    path = shared / "ttyDXL"
    as_other_user(f"ln -s /dev/pts/999999 {path}")
    info = os.lstat(path)
    # The record a server of ours would have left for exactly this link.
    key = str(path)
    made = f"link {info.st_dev} {info.st_ino} {info.st_uid} /dev/pts/999999"
    records = shared / f"{CLAIM_DIR_NAME}-{os.geteuid()}"
    record = records / (hashlib.sha256(key.encode()).hexdigest()[:32] + ".claim")
    as_other_user(
        f"mkdir -m 0777 {records} && printf 'pid 1: sim bus\\n%s\\n%s\\n' '{key}' '{made}' "
        f"> {record} && chmod 0666 {record}"
    )
    before = _snapshot(path)
    _refused(
        [*SERVERS["sim bus --link"], str(path)],
        f"{records} belongs to uid {other_uid()}",
        f"rm -r {records}",
    )
    assert _snapshot(path) == before and record.read_text().startswith("pid 1")


def _start_and_kill(args: list[str], tmpdir: Path) -> None:
    """Start ``snakebot ARGS`` with ``tmpdir`` as its temporary directory, wait until it
    serves, and SIGKILL it: what it made stays behind, with its record."""
    environ = {k: v for k, v in os.environ.items() if k != RUNTIME_ENV}
    proc = subprocess.Popen(
        [sys.executable, "-m", "snakebot", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environ | {"TMPDIR": str(tmpdir)},
    )
    try:
        assert proc.stdout is not None
        while "stops." not in (line := proc.stdout.readline()):
            assert line, proc.stderr.read() if proc.stderr else ""
    finally:
        proc.kill()
        proc.communicate(timeout=30)


def test_a_dead_servers_link_swapped_by_another_user_is_refused(shared, ours):
    # A directory the other user owns and lets everyone write (no sticky bit): they may
    # replace the link a killed server of ours left, with one to the same pty or to our file.
    room = shared / "room"
    as_other_user(f"mkdir -m 0777 {room}")
    path = room / "ttyDXL"
    args = [*SERVERS["sim bus --link"], str(path)]
    for target in ("same", str(ours)):
        _start_and_kill(args, shared)
        pty = os.readlink(path)
        aim = pty if target == "same" else target
        as_other_user(f"ln -s {aim} {path}.new && mv -f {path}.new {path}")
        before = _snapshot(path)
        assert before[1] == other_uid() and before[3] == aim
        _refused(args, "which no snakebot server made (or it was replaced since)")
        assert _snapshot(path) == before
        assert ours.read_bytes() == PRECIOUS
        as_other_user(f"rm {path}")
