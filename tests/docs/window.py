"""Running a line that opens MuJoCo's viewer (`snakebot sim view`) as a reader does: a
`snakebot` process of its own on the display DISPLAY names (the test's Xvfb), its port
replaced by the emulated controller's (a pseudo-terminal of the test's process,
tests/docs/runnable.py). With ``--once`` it must close by itself with exit status 0; else
its window must show a picture (:class:`stopping.WindowJob`), then Ctrl-C must close it
with exit status 130 and ``interrupted``. A process of its own, as a reader's viewer is:
its GL context and drawing thread stay out of the test's process, where other viewer
tests (tests/plots/test_viewer.py) may run after it."""

from __future__ import annotations

import os
import signal
import subprocess
import threading

from runnable import SNAKEBOT, Emulators, Line, arguments
from stopping import LiveRunner, WindowJob

WINDOW_TIMEOUT_S = 120.0


class Process(LiveRunner):
    """A running process's stderr, read as a running command's output is
    (:meth:`LiveRunner.wait`)."""

    def __init__(self, process: subprocess.Popen[str]) -> None:
        super().__init__()
        self.process = process
        self.lines: list[str] = []
        assert process.stderr is not None
        self.reader = threading.Thread(target=self.lines.extend, args=(process.stderr,))
        self.reader.start()

    def printed(self) -> str:
        self.ended = self.process.poll() is not None
        return "".join(self.lines)

    def end(self) -> tuple[int, str]:
        """The exit status and all it printed on stderr, once it has ended."""
        status = self.process.wait(timeout=WINDOW_TIMEOUT_S)
        self.reader.join()
        return status, "".join(self.lines)


def window(line: Line, emulators: Emulators) -> list[str]:
    """Run the `sim view` ``line``: the problems found."""
    args, env = arguments(line.commands[0], emulators)
    once = "--once" in args
    process = subprocess.Popen(
        [SNAKEBOT, *args],
        env={**os.environ, **env},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    live = Process(process)
    problems = []
    try:
        if not once:
            try:
                WindowJob().ready(live)
            except AssertionError as exc:
                problems.append(f"before Ctrl-C: {exc}")
            process.send_signal(signal.SIGINT)
        status, said = live.end()
    finally:
        if process.poll() is None:
            process.kill()
            live.end()
    want = 0 if once else 128 + signal.SIGINT
    if status != want or "Traceback" in said or "the viewer is open" not in said:
        problems.append(f"exited {status} ({want} expected): {said[-600:]}")
    elif not once and not said.strip().endswith("interrupted"):
        problems.append(f"did not end with `interrupted`: {said[-600:]}")
    return [f"{line.where}: `{line.text}` in a window: {p}" for p in problems]
