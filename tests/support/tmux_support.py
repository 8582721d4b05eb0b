"""A real terminal for the tests of commands that read the keyboard (`snakebot drive`):
a detached tmux session on a private server, its screen read as text, keys sent to it."""

from __future__ import annotations

import contextlib
import re
import shutil
import subprocess
import time
import uuid
from collections.abc import Callable

import pytest

SCREEN_TIMEOUT_S = 20.0
ROW = re.compile(r"^\s*(phi\d)\s+(\d+)\s+([-+]\d+\.\d)\s+([-+]\d+\.\d)\s+([-+]\d+\.\d)\s+(\S.*)$")
"""A joint's row of `snakebot drive`'s screen: name, servo ID, goal, present, load, errors."""


class Tmux:
    """One detached tmux session on a private server, running ``command`` in ``folder``."""

    def __init__(self, command: str, folder: str | None = None) -> None:
        if shutil.which("tmux") is None:
            pytest.fail("tmux missing: run `make setup`")
        self.socket = f"snakebot-drive-{uuid.uuid4().hex[:8]}"
        where = ["-c", folder] if folder else []
        self._tmux("new-session", "-d", "-s", "drive", "-x", "120", "-y", "30", *where, command)

    def _tmux(self, *args: str) -> str:
        done = subprocess.run(
            ["tmux", "-L", self.socket, *args], capture_output=True, text=True, check=True
        )
        return done.stdout

    def keys(self, *keys: str) -> None:
        self._tmux("send-keys", "-t", "drive", *keys)

    def screen(self) -> str:
        return self._tmux("capture-pane", "-p", "-t", "drive")

    def wait_for(self, seen: Callable[[str], bool], what: str) -> str:
        deadline = time.monotonic() + SCREEN_TIMEOUT_S
        while time.monotonic() < deadline:
            text = self.screen()
            if seen(text):
                return text
            time.sleep(0.1)
        pytest.fail(f"the screen never showed {what}:\n{self.screen()}")

    def close(self) -> None:
        with contextlib.suppress(subprocess.CalledProcessError):
            self._tmux("kill-server")


def joints(screen: str) -> dict[str, float]:
    """Joint name -> the angle column (present position, degrees) on drive's screen."""
    rows = (ROW.match(line) for line in screen.splitlines())
    return {m.group(1): float(m.group(4)) for m in rows if m}
