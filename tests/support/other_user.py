"""A second local user for the tests that play a hostile neighbour: shell commands run
under ``nobody`` (a real other uid, as root can do here and in CI), and a shared
directory with the permissions of ``/tmp`` (1777) where both users can make files."""

from __future__ import annotations

import os
import pwd
import shutil
import stat
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

OTHER = "nobody"


def other_uid() -> int:
    return pwd.getpwnam(OTHER).pw_uid


needs_root = pytest.mark.skipif(
    os.geteuid() != 0, reason="switching to another user needs root (CI runs as root)"
)


def as_other_user(script: str) -> None:
    """Run the shell ``script`` as the other user; it must succeed."""
    uid = other_uid()
    gid = pwd.getpwnam(OTHER).pw_gid
    subprocess.run(
        ["sh", "-ec", script],
        check=True,
        timeout=30,
        user=uid,
        group=gid,
        extra_groups=[],
        env={"PATH": "/usr/bin:/bin"},
    )


@pytest.fixture
def shared_tmp() -> Iterator[Path]:
    """A sticky, world-writable directory, like /tmp, that both users can reach."""
    path = Path(tempfile.mkdtemp(prefix="snakebot-shared-", dir="/tmp"))
    path.chmod(stat.S_ISVTX | stat.S_IRWXU | stat.S_IRWXG | stat.S_IRWXO)
    yield path
    shutil.rmtree(path, ignore_errors=True)
