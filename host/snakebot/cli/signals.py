"""The signals that stop a serving command cleanly (QEMU stopped, work directories and
links removed): Ctrl-C, SIGTERM, and SIGHUP (the terminal closed)."""

from __future__ import annotations

import signal

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
