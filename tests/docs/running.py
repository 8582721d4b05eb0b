"""How a line of each kind (tests/docs/runnable.py) runs here, and which kinds do not."""

from __future__ import annotations

import os
from pathlib import Path

from click.testing import Result
from make_flash import make_flash
from runnable import Emulators, Line, run_line
from stopping import ctrl_c
from terminal import drive
from window import window

NOT_RUN = ("hardware", "video")
"""Kinds not run: a real board's line (marked in the text), a video (declared with its
cost where it is shown)."""
STOPPED = ("until Ctrl-C", "emulator")
OVER_BUDGET = "CPU seconds measured here, over the suite's time budget"
"""Why a line costlier than a test may be is not run (after its cost: `5.2 {OVER_BUDGET}`)."""


def how(line: Line) -> str:
    """How ``line`` runs, for the inventory: run, run and stopped with Ctrl-C, in a
    terminal, in a window, by make; or, for a kind not run, the kind."""
    kind = line.kind
    if kind == "window":
        return "run in a window" + ("" if "--once" in line.text else ", stopped with Ctrl-C")
    return {
        "run": "run",
        "until Ctrl-C": "run, stopped with Ctrl-C",
        "emulator": "run, stopped with Ctrl-C",
        "terminal": "run in a terminal",
        "make": "run by make",
    }.get(kind, kind)


def run_any(line: Line, emulators: Emulators) -> tuple[Result | None, list[str]]:
    """Run ``line`` (in the current folder) the way its kind runs: the result of the
    command when it ran in process (else None), and the problems found. A window needs
    the display that DISPLAY names (the caller's X server)."""
    kind = line.kind
    if kind == "window" and not os.environ.get("DISPLAY"):
        return None, [f"{line.where}: `{line.text}` needs a display (the xvfb fixture)"]
    if kind == "run":
        return run_line(line, emulators)
    if kind in STOPPED:
        return ctrl_c(line, emulators)
    if kind == "window":
        return None, window(line, emulators)
    if kind == "terminal":
        return None, drive(line, emulators, Path.cwd())
    if kind == "make":
        return None, make_flash(line, emulators)
    return None, [f"{line.where}: `{line.text}` ({kind}) cannot run here"]
