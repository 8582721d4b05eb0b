"""Temporary working directories of the emulator (QEMU's flash image and log, the bus
socket), named after the process that made them so that one left behind by a process
that was killed (SIGKILL: no chance to clean up) is removed by the next one to start."""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from pathlib import Path

PREFIX = "snakebot-"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process
    return True


def sweep_stale(kind: str) -> list[Path]:
    """Remove this user's ``kind`` work directories whose process is gone; return them."""
    pattern = re.compile(rf"{re.escape(PREFIX + kind)}-(\d+)-")
    removed = []
    for path in Path(tempfile.gettempdir()).glob(f"{PREFIX}{kind}-*-*"):
        m = pattern.match(path.name)
        try:
            mine = path.is_dir() and path.stat().st_uid == os.getuid()
        except OSError:
            continue
        if m and mine and not _alive(int(m.group(1))):
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


def make_workdir(kind: str) -> str:
    """A new work directory for ``kind`` ("serve", "qemu"), after removing stale ones."""
    sweep_stale(kind)
    return tempfile.mkdtemp(prefix=f"{PREFIX}{kind}-{os.getpid()}-")
