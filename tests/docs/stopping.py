"""Running a line that does not end by itself (issue #29): an emulator that serves until
Ctrl-C (`sim serve`, `sim bus --pty`, `sim bootloader`), a looping `bus play`, a `monitor`
with no duration. The line runs in process (click's CliRunner) in the main thread, as in
a terminal; beside it a thread waits until the line has done its job, checked from
outside as a user would see it (the pseudo-terminal it printed answers a PING, the
Foxglove server it started hands a real WebSocket client /joint_states, the monitor
printed samples), then presses Ctrl-C (SIGINT to the main thread). The line must then
exit 130 with ``interrupted`` and no traceback, and leave nothing running that it
started: no thread, no child process (QEMU), no open pseudo-terminal. (A viewer's window
runs as a process of its own, tests/docs/window.py, with :class:`WindowJob` as its job.)
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import ClassVar, TypeVar

import serial
from click.testing import CliRunner, Result
from foxglove_client import Listener
from runnable import ANSWERS, Emulators, Line, arguments

from snakebot.cli import main

CORNER = (400, 300)
"""Width and height of the corner of the display a window's picture is looked for in."""
PICTURE_COLOURS = 20
"""More colours than that in CORNER is a picture: a blank display has 1-2; the viewer's
picture of snake5 on the floor had 42-57 (11 looks, once per second)."""
JOB_TIMEOUT_S = 30.0
"""Seconds a line has to do its job before it gets its Ctrl-C anyway (and fails)."""
SETTLE_S = 5.0
"""Seconds the threads a line started have to end once it has exited."""

T = TypeVar("T")


class LiveRunner(CliRunner):
    """A CliRunner whose output can be read while the command still runs."""

    streams: tuple | None = None
    ended = False

    @contextlib.contextmanager
    def isolation(self, *args, **kwargs) -> Iterator[tuple]:  # type: ignore[override]
        with super().isolation(*args, **kwargs) as streams:
            self.streams = streams
            try:
                yield streams
            finally:
                self.ended = True

    def printed(self) -> str:
        """What the command has printed so far (stdout and stderr)."""
        return self.streams[-1].getvalue().decode(errors="replace") if self.streams else ""

    def wait(self, done: Callable[[], T | None], what: str) -> T:
        """``done()``'s first true value, polled while the command runs: an
        AssertionError if the command ends first or JOB_TIMEOUT_S passes."""
        deadline = time.monotonic() + JOB_TIMEOUT_S
        while not (value := done()):
            if self.ended:
                raise AssertionError(f"it ended before {what}: {self.printed()[-600:]!r}")
            if time.monotonic() > deadline:
                raise AssertionError(f"no {what} in {JOB_TIMEOUT_S:g} s: {self.printed()[-600:]!r}")
            time.sleep(0.05)
        return value

    def found(self, pattern: str, what: str) -> re.Match[str]:
        """The first match of ``pattern`` in what the command printed, once it is there."""
        return self.wait(lambda: re.search(pattern, self.printed()), what)


@dataclass(frozen=True)
class Running:
    """What a process has running: its Python threads, its child processes and the
    pseudo-terminals it holds open."""

    threads: frozenset[threading.Thread]
    children: frozenset[int]
    ptys: frozenset[str]

    @classmethod
    def now(cls) -> Running:
        children: set[int] = set()
        for task in os.listdir("/proc/self/task"):
            with contextlib.suppress(OSError), open(f"/proc/self/task/{task}/children") as f:
                children.update(int(pid) for pid in f.read().split())
        ptys = set()
        for fd in os.listdir("/proc/self/fd"):
            with contextlib.suppress(OSError):
                target = os.readlink(f"/proc/self/fd/{fd}")
                if target == "/dev/ptmx" or target.startswith("/dev/pts/"):
                    ptys.add(f"fd {fd} -> {target}")
        return cls(frozenset(threading.enumerate()), frozenset(children), frozenset(ptys))

    def left(self, before: Running) -> list[str]:
        threads = [t.name for t in self.threads - before.threads if t.is_alive()]
        return [
            f"{what} left running: {sorted(map(str, items))}"
            for what, items in (
                ("threads", threads),
                ("child processes", self.children - before.children),
                ("pseudo-terminals", self.ptys - before.ptys),
            )
            if items
        ]


def left_running(before: Running) -> list[str]:
    """What runs now that did not before, once the threads have had SETTLE_S to end."""
    deadline = time.monotonic() + SETTLE_S
    while (left := Running.now().left(before)) and time.monotonic() < deadline:
        time.sleep(0.1)
    return left


@dataclass
class Job:
    """What a line must have done before it gets Ctrl-C (:meth:`ready`, in a thread beside
    it) and what it must have printed by its end (:meth:`after`)."""

    foxglove: int | None = None
    listener: Listener | None = field(default=None, init=False)
    says_interrupted: ClassVar[bool] = True
    """Whether the line's last word is ``interrupted`` (the stop every command shares)."""

    def start(self) -> None:
        if self.foxglove is not None:  # a real Foxglove client, from before the server
            self.listener = Listener(self.foxglove, ["/joint_states"], timeout=JOB_TIMEOUT_S)

    def ready(self, live: LiveRunner) -> None:
        listener = self.listener
        if listener is not None:
            live.wait(
                lambda: listener.error or listener.messages.get("/joint_states"),
                f"/joint_states for a Foxglove client on ws://127.0.0.1:{self.foxglove}",
            )
            if listener.error is not None:
                raise AssertionError(f"the Foxglove client: {listener.error!r}")

    def after(self, result: Result) -> None:
        if self.listener is not None:
            self.listener.stop()


class ServeJob(Job):
    """`sim serve`: the controller on the PC link it printed answers (its identity)."""

    def ready(self, live: LiveRunner) -> None:
        from snakebot.cli.options import ControllerLink

        pc_link = live.found(r"PC link \(USART3\): (\S+)", "PC link")[1]
        with ControllerLink(pc_link).open() as ctl:
            ctl.identify()
        super().ready(live)


class BusJob(Job):
    """`sim bus --pty`: each servo it printed answers a PING on the pseudo-terminal."""

    def ready(self, live: LiveRunner) -> None:
        from snakebot.link.transport import DxlClient

        ids = live.found(r"IDs ([\d, ]+)\n", "servo IDs")[1]
        device = live.found(r"serving on (\S+)", "device")[1]
        with DxlClient(device, 1_000_000) as client:
            for servo in ids.split(", "):
                client.ping(int(servo))


class BootloaderJob(Job):
    """`sim bootloader --link PATH`: the bootloader answers '#' on PATH with its prompt,
    as `snakebot flash` catches it."""

    def __init__(self, link: str) -> None:
        super().__init__()
        self.link = link

    def ready(self, live: LiveRunner) -> None:
        from snakebot.facts.boards import PC_LINK_BAUD
        from snakebot.link.flash.bootloader import enter_bootloader
        from snakebot.link.flash.settings import FlashTimeouts

        live.found(re.escape(f"(link {self.link})"), "link")
        with serial.Serial(self.link, PC_LINK_BAUD, timeout=0.1) as port:
            said = enter_bootloader(port, FlashTimeouts.resolve())
        if b">" not in said:
            raise AssertionError(f"the bootloader answered '#' with {said!r}, no prompt")


class MonitorJob(Job):
    """`monitor`: it printed samples of the controller (two at least) before Ctrl-C."""

    def ready(self, live: LiveRunner) -> None:
        live.wait(lambda: live.printed().count(" state ") >= 2, "two samples")
        super().ready(live)


@dataclass
class Timed(Job):
    """A line that gets Ctrl-C after ``seconds``."""

    seconds: float = 1.5

    def ready(self, live: LiveRunner) -> None:
        time.sleep(self.seconds)
        super().ready(live)


class LoopJob(Timed):
    """A looping `bus play`: it plays (1.5 s), then at Ctrl-C slows the gait to a halt and
    says, in place of ``interrupted``, how long it played, stopped by Ctrl-C, and where
    the servos hold."""

    says_interrupted = False

    def after(self, result: Result) -> None:
        super().after(result)
        played = re.search(r"Played (\d+\.\d+) s of \S+ \(stopped by Ctrl-C\)", result.stdout)
        if played is None or float(played[1]) < 1.0 or "servos hold at tick" not in result.stdout:
            raise AssertionError(f"it did not say it played for a second: {result.stdout!r}")


class WindowJob(Job):
    """`sim view`: the viewer said it is open, and its window on the display shows a
    picture (the robot on the floor's grid: many colours, not a blank screen)."""

    def ready(self, live: LiveRunner) -> None:
        import numpy as np
        from PIL import ImageGrab

        def colours() -> int:
            """The colours of the window's corner (no window manager: it is at the top
            left), a pixel in four: a look short enough for the emulated controller this
            process serves to answer the viewer meanwhile."""
            box = (0, 0, *CORNER)
            shot = ImageGrab.grab(bbox=box, xdisplay=os.environ["DISPLAY"]).convert("RGB")
            time.sleep(0.5)
            return len(np.unique(np.asarray(shot)[::2, ::2].reshape(-1, 3), axis=0))

        live.found(r"the viewer is open", "word that the viewer is open")
        live.wait(lambda: colours() > PICTURE_COLOURS, "picture on the display")


def job_for(words: list[str], emulators: Emulators) -> Job:
    """The job of a line that runs until Ctrl-C, by its command (``words``, as it runs)."""
    foxglove = emulators.foxglove
    command = tuple(words[1:3])
    if command == ("sim", "serve"):
        return ServeJob(foxglove)
    if command == ("sim", "bus"):
        return BusJob(foxglove)
    if command == ("sim", "bootloader"):
        return BootloaderJob(words[words.index("--link") + 1])
    if command[:1] == ("monitor",):
        return MonitorJob(foxglove)
    if command == ("bus", "play"):
        return LoopJob(foxglove)
    raise AssertionError(f"no job known for `{' '.join(words)}`")


def ctrl_c(
    line: Line, emulators: Emulators, job: Callable[[list[str]], Job] | None = None
) -> tuple[Result | None, list[str]]:
    """Run ``line`` (a command that runs until Ctrl-C) until it has done its job, then
    press Ctrl-C: the result (None if it ended by itself first) and the problems found."""
    args, env = arguments(line.commands[0], emulators)
    the_job = (job or (lambda words: job_for(words, emulators)))(["snakebot", *args])
    problems: list[str] = []
    ended, pressing = threading.Event(), threading.Lock()
    before = Running.now()

    def watch() -> None:
        try:
            the_job.ready(runner)
        except Exception as exc:  # noqa: BLE001 - a failed check, reported with the line's
            problems.append(f"before Ctrl-C: {exc}")
        with pressing:  # Ctrl-C only while the command runs
            if not ended.is_set():
                signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)

    runner = LiveRunner()
    the_job.start()
    watcher = threading.Thread(target=watch, name="docs-ctrl-c", daemon=True)
    watcher.start()
    try:
        result: Result | None = runner.invoke(main, args, env=env, input=ANSWERS)
        with pressing:
            ended.set()
    except KeyboardInterrupt:  # the command had ended when Ctrl-C came
        result = None
        problems.append("it ended before Ctrl-C")
    watcher.join()
    if result is not None:
        problems += exit_problems(result, the_job.says_interrupted)
        try:
            the_job.after(result)
        except AssertionError as exc:
            problems.append(str(exc))
    elif the_job.listener is not None:
        the_job.listener.stop()
    problems += left_running(before)
    return result, [f"{line.where}: `{line.text}`: {p}" for p in problems]


def exit_problems(result: Result, says_interrupted: bool = True) -> list[str]:
    """A command that got Ctrl-C exits 130, shows no traceback and says ``interrupted``
    last (``says_interrupted``)."""
    output = (result.stderr or result.stdout).strip()
    if result.exit_code != 128 + signal.SIGINT or "Traceback" in result.output:
        return [f"exited {result.exit_code} after Ctrl-C (130 expected): {output[-600:]}"]
    if says_interrupted and not result.stderr.strip().endswith("interrupted"):
        return [f"did not end with `interrupted`: {output[-600:]}"]
    return []
