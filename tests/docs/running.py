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

NOT_RUN = ("hardware",)
"""Kinds not run: a real board's line (marked in the text)."""
VIDEO_FRAMES = 2
"""Frames a `--video` line's file must hold at least, as ffmpeg decodes it (a still
picture, or a file cut short, decodes to fewer or none)."""
STOPPED = ("until Ctrl-C", "emulator")


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
        "video": "run, its video decoded",
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
    if kind == "video":
        result, problems = run_line(line, emulators)
        return result, problems or video(line)
    return None, [f"{line.where}: `{line.text}` ({kind}) cannot run here"]


def video(line: Line) -> list[str]:
    """The video a `--video` line wrote decodes, as ffmpeg reads it, to VIDEO_FRAMES or
    more frames."""
    from imageio_ffmpeg import count_frames_and_secs

    words = line.commands[-1]
    path = Path(words[words.index("--video") + 1])
    try:
        frames, seconds = count_frames_and_secs(str(path))
    except (OSError, RuntimeError) as error:
        last = str(error).strip().splitlines()[-1]  # ffmpeg's own reason
        return [f"{line.where}: `{line.text}`: ffmpeg cannot read {path}: {last}"]
    if frames < VIDEO_FRAMES:
        return [f"{line.where}: `{line.text}`: {path} holds {frames} frames ({seconds} s)"]
    return []
