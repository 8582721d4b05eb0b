"""Running ``make flash PORT=/dev/ttyUSB0`` as written, in the checkout, its port replaced by
the emulated bootloader's (tests/docs/runnable.py): make builds what is not built, then runs
`snakebot flash` on the image, which the emulated CM-530 starts after GO and the flasher
verifies. A checkout whose .venv is not set up (or is older than the package's files)
would make `make flash` set it up first, installing packages: that is reported as the
problem, not done in a test (`make test` sets it up before it runs the tests)."""

from __future__ import annotations

import os
import subprocess

from runnable import Emulators, Line

from snakebot.paths import REPO_ROOT

MAKE_TIMEOUT_S = 120.0
MAKE_ENV_NAMES = ("MAKEFLAGS", "MFLAGS", "MAKELEVEL")
"""What a `make test` above this test passes down to its commands: a make started here is
the reader's own, not a sub-make of that one (whose job server it cannot reach)."""


def make_flash(line: Line, emulators: Emulators) -> list[str]:
    """Run the ``make flash PORT=...`` ``line``: the problems found."""
    env = {k: v for k, v in os.environ.items() if k not in MAKE_ENV_NAMES}
    ready = subprocess.run(
        ["make", "-q", "runtime-env"], cwd=REPO_ROOT, env=env, capture_output=True
    )
    if ready.returncode != 0:
        return [
            f"{line.where}: `{line.text}` would first set up {REPO_ROOT}/.venv: run "
            "`make setup` (make test does)"
        ]
    port = emulators.bootloader_port()
    words = [f"PORT={port}" if w.startswith("PORT=") else w for w in line.commands[0]]
    done = subprocess.run(
        words, cwd=REPO_ROOT, env=env, capture_output=True, text=True, timeout=MAKE_TIMEOUT_S
    )
    if done.returncode != 0 or "Verified: controller at ID" not in done.stdout:
        return [
            f"{line.where}: `{line.text}` exited {done.returncode}: "
            f"{(done.stdout + done.stderr)[-800:]}"
        ]
    return []
