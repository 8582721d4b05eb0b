"""Running the commands the documents and the help texts show, against the emulators.

A command line is one of:

* **run**: a ``snakebot`` command, run in process (click's CliRunner) in a shared work
  folder, its real-hardware port (``/dev/ttyUSB0``, ``/dev/pts/N``, ``/tmp/ttyCM530``)
  replaced by an emulator's: ``sim://`` servos for the servo-bus commands, the
  controller's C device on a pseudo-terminal (:class:`ControllerPty`, what the firmware
  runs on its PC link) for the controller commands, the emulated ROBOTIS bootloader for
  ``flash``, the CM-530's image on the emulated chip for ``doctor --board cm530`` (the
  one a flash started, if any);
* **hardware**: marked ``# real hardware only`` in the text, not run;
* **until Ctrl-C**: a command that runs until interrupted, as its help says (a looping
  ``bus play``, ``monitor`` without a duration): run until it has done its job, then
  given Ctrl-C (tests/docs/stopping.py);
* **emulator**: a line that starts an emulator (``snakebot sim serve``, ``sim
  bootloader``, ``sim bus --pty``), which serves until Ctrl-C: run the same way (its
  job: what it printed answers); the lines that follow it reach the test's own
  emulators, as a reader's second shell would reach the line's;
* **terminal**: ``drive`` reading the keyboard: run in a real terminal (tmux), driven
  by keys, ended with q (tests/docs/terminal.py);
* **window**: a line that opens MuJoCo's viewer (``snakebot sim view``): run as a process
  on an X server of the test's (Xvfb), closed with Ctrl-C unless it closes by itself
  (``--once``; tests/docs/window.py);
* **make**: ``make flash PORT=...``: run as written in the checkout against the emulated
  bootloader (tests/docs/make_flash.py);
* **video**: a line that renders a video: declared with its measured cost where it is
  shown, and not run (the videos have their own tests in tests/plots).

A fixed Foxglove port (``--foxglove 8765``) is replaced by a free one and a fixed link
(``--link /tmp/ttyCM530``) by one in a folder of the test's, as a real-hardware port is
replaced by an emulator's: the same port may be busy on a user's machine, and is between
tests that run side by side.

Anything else (a ``make`` or ``pip`` line not marked) is an error: mark it or make it run.
"""

from __future__ import annotations

import itertools
import re
import shlex
import shutil
import sys
import tempfile
import textwrap
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import click
from click.testing import CliRunner, Result
from foxglove_client import free_port
from py_library import FlashController, PyStore

from snakebot.cli import main
from snakebot.sim.bootloader import Bootloader, BootloaderPty
from snakebot.sim.controller_pty import ControllerPty
from snakebot.sim.serve import EmulatedRobot

HARDWARE = "real hardware only"
PORT = re.compile(r"^(?:/dev/tty\w+|/dev/pts/\w+|/tmp/ttyCM530|COM\d+)$")
ENV = re.compile(r"^[A-Z][A-Z0-9_]*=")
EMULATORS = (("sim", "serve"), ("sim", "bootloader"), ("sim", "bus"))
WINDOW = ("sim", "view")
BUS_COMMANDS = (("bus",), ("robot", "calibrate"))
SNAKE5_IDS = "10,11,15,16"
ANSWERS = "\n" + "y\n" * 20  # Enter, then yes to every question (robot calibrate)
EXAMPLE = re.compile(r"^\s*(?:Example:\s*)?(snakebot\s.+)$")
BUS_NAMES = itertools.count(1)  # a named sim:// bus lives as long as the process
SNAKEBOT = str(Path(sys.executable).with_name("snakebot"))
"""The `snakebot` command of the Python running the tests, as a reader's shell finds it."""


@dataclass
class Line:
    """One command line as the text shows it, and where."""

    text: str
    where: str

    @property
    def comment(self) -> str:
        head, _, tail = self.text.partition(" #")
        return tail.strip() if head else ""

    @property
    def commands(self) -> list[list[str]]:
        """The words of each command (``a && b`` is two), comments and ``$ `` left out."""
        text = self.text.removeprefix("$ ")
        return [shlex.split(part, comments=True) for part in text.split("&&")]

    @property
    def kind(self) -> str:
        if HARDWARE in self.comment:
            return "hardware"
        words = [w for w in self.commands[0] if not ENV.match(w)]
        if words[:2] == ["make", "flash"]:
            return "make"
        if words[:1] != ["snakebot"]:
            return "unmarked"
        if tuple(words[1:3]) in EMULATORS:
            return "emulator"
        if words[1:2] == ["drive"] and "--keys" not in words and "--script" not in words:
            return "terminal"
        if any(until(c[1:]) for c in self.commands):
            return "until Ctrl-C"
        if "--video" in words:
            return "video"
        if tuple(words[1:3]) == WINDOW:
            return "window"
        return "run"


def until(words: list[str]) -> bool:
    """Whether a command runs until Ctrl-C, as its help says: a looping `bus play`, a
    `monitor` with no duration."""
    if words[:2] == ["bus", "play"]:
        return "--loop" in words
    if words[:1] == ["monitor"]:
        return "--duration" not in words
    return False


def help_examples() -> Iterator[Line]:
    """Every example line of every command's --help."""

    def walk(cmd: click.Command, path: list[str]) -> Iterator[tuple[list[str], click.Command]]:
        yield path, cmd
        if isinstance(cmd, click.Group):
            ctx = click.Context(cmd)
            for name in cmd.list_commands(ctx):
                sub = cmd.get_command(ctx, name)
                if sub is not None:
                    yield from walk(sub, [*path, name])

    for path, cmd in walk(main, []):
        lines = (cmd.help or "").splitlines()
        for number, text in enumerate(lines):
            if m := EXAMPLE.match(text):
                command = m.group(1).strip()
                for more in lines[number + 1 :]:  # an example wrapped onto option lines
                    if not more.strip().startswith("-"):
                        break
                    command += " " + more.strip()
                yield Line(command, f"snakebot {' '.join(path)} --help, line {number}")


def block_lines(source: str, where: str) -> Iterator[Line]:
    """The command lines of a fenced block: every line in a ``sh`` block; in a
    ``console`` block the lines that start with ``$ `` (the rest is expected output)."""
    console = any(line.startswith("$ ") for line in source.splitlines())
    for number, text in enumerate(source.splitlines()):
        if text.strip() and not text.lstrip().startswith("#"):
            if not console or text.startswith("$ "):
                yield Line(text.strip(), f"{where}+{number}")


@dataclass
class Emulators:
    """The emulators the commands reach, started when first needed, one of each."""

    controller: ControllerPty | None = None
    bootloader: BootloaderPty | None = None
    handover: object | None = None
    board: EmulatedRobot | None = None
    buses: int = 0
    robot: str = "snake5"
    """The robot whose servos the controller's bus has."""
    foxglove: int | None = None
    """The free port that replaced the last line's Foxglove port."""
    links: str | None = None
    """The folder of the links (``--link``) that replace the lines' fixed ones."""

    def link(self, fixed: str) -> str:
        """A link in a folder of the emulators' in place of ``fixed``."""
        if self.links is None:
            self.links = tempfile.mkdtemp(prefix="snakebot-docs-")
        return f"{self.links}/{Path(fixed).name}"

    def controller_port(self) -> str:
        """The controller's C logic with a gait library (a Python store that writes a
        step per tick, as the CM-530's flash does) and the robot's servos (after a flash,
        in place of the board it flashed, whose chip emulation would run on meanwhile)."""
        if self.handover is not None:
            self.close()
        if self.controller is None:
            self.controller = ControllerPty(robot=self.robot)
            store = PyStore()
            store.write_in_background()
            self.controller.device_logic = FlashController(self.controller.bus, store)
            self.controller.start()
        return self.controller.device

    def bootloader_port(self) -> str:
        """A board in its bootloader, anew for each flash (as if MODE had been pressed),
        which starts the image it receives on the emulated CM-530 after GO, as `snakebot
        sim bootloader` does."""
        from snakebot.sim.mcu.handover import McuHandover  # the mcu extra, as the CLI

        self.close()
        self.handover = McuHandover()
        self.bootloader = BootloaderPty(Bootloader(), pace=False, on_go=self.handover).start()
        return self.bootloader.device

    def bus_port(self, words: list[str]) -> str:
        """The emulated bus these lines share (it keeps its servos' settings from one
        line to the next): servo 1, the factory ID, and snake5's servos, unless a line
        renumbers servo 1 (then servo 1 alone)."""
        if not self.buses:
            self.buses = next(BUS_NAMES)
        ids = "1" if words[:2] == ["bus", "set-id"] else f"1,{SNAKE5_IDS}"
        return f"sim://docs{self.buses}?ids={ids}"

    def cm530_port(self) -> str:
        """The CM-530's own image on the emulated chip (`snakebot sim serve --board
        cm530`): the board a flash here started, or else one of its own."""
        if self.handover is not None:
            assert self.bootloader is not None
            return self.bootloader.device  # after GO the line reaches the new firmware
        if self.board is None:
            self.close()
            self.board = EmulatedRobot(self.robot, board="cm530")
            self.board.start()
        return self.board.info.pc_link

    def port_for(self, words: list[str]) -> str:
        if words[:1] == ["flash"] or (words[:1] == ["doctor"] and "--bootloader" in words):
            return self.bootloader_port()
        if words[:1] == ["doctor"] and "cm530" in words:
            return self.cm530_port()
        if any(tuple(words[: len(c)]) == c for c in BUS_COMMANDS):
            return self.bus_port(words)
        return self.controller_port()

    def close(self) -> None:
        for server in (self.controller, self.bootloader):
            if server is not None:
                server.close()
        close = getattr(self.handover, "close", None)
        if close is not None:
            close()
        if self.board is not None:
            self.board.stop()
        self.controller = self.bootloader = self.handover = self.board = None
        if self.links is not None:
            shutil.rmtree(self.links, ignore_errors=True)
            self.links = None


def arguments(words: list[str], emulators: Emulators) -> tuple[list[str], dict[str, str]]:
    """The arguments of ``snakebot WORDS`` and the environment its leading ``NAME=value``
    words set, a real-hardware port replaced by the emulator's, a fixed Foxglove port by a
    free one, a fixed link by one in the emulators' folder."""
    words = list(words)
    env = {}
    while words and ENV.match(words[0]):
        name, _, value = words.pop(0).partition("=")
        env[name] = value
    args = words[1:]
    emulators.foxglove = free_port() if "--foxglove" in args else None
    replaced = []
    for before, word in zip(["", *args[:-1]], args, strict=True):
        if before == "--foxglove":
            word = str(emulators.foxglove)
        elif before == "--link":
            word = emulators.link(word)
        elif PORT.match(word):
            word = emulators.port_for(args)
        replaced.append(word)
    return replaced, env


def invoke(words: list[str], emulators: Emulators) -> Result:
    """Run ``snakebot WORDS`` in process, with :func:`arguments`."""
    args, env = arguments(words, emulators)
    return CliRunner().invoke(main, args, env=env, input=ANSWERS)


def run_line(line: Line, emulators: Emulators) -> tuple[Result, list[str]]:
    """Run a ``run`` line (in the current folder): the last command's result, and the
    problems found (none: it worked)."""
    for words in line.commands:
        result = invoke(words, emulators)
        if result.exit_code != 0:
            return result, [
                f"{line.where}: `{line.text}` exited {result.exit_code}: "
                f"{(result.stderr or result.stdout).strip()[-600:]}"
            ]
    return result, []


def run_console(source: str, where: str, emulators: Emulators) -> list[str]:
    """A ``console`` block: each ``$ `` command runs, and the lines under it must be in
    what it printed (its exit status is then whatever the text shows it to be)."""
    problems: list[str] = []
    blocks = re.split(r"^\$ ", source, flags=re.M)[1:]
    for number, block in enumerate(blocks):
        command, _, expected = block.partition("\n")
        line = Line(f"$ {command.strip()}", f"{where}+{number}")
        if line.kind != "run":
            continue
        result = invoke(line.commands[0], emulators)
        printed = result.stdout + result.stderr
        for want in filter(None, (w.strip() for w in expected.splitlines())):
            if want not in printed:
                problems.append(f"{line.where}: `{command}` did not print {want!r}: {printed!r}")
    return problems


def program_spec() -> str:
    """The program spec `snakebot program build --help` shows, as a file would hold it."""
    ctx = click.Context(main)
    build = main.get_command(ctx, "program").get_command(ctx, "build")  # type: ignore[union-attr]
    lines = (build.help or "").splitlines()
    start = next(n for n, text in enumerate(lines) if text.strip() == "\b") + 1
    end = next(n for n in range(start, len(lines)) if not lines[n].strip())
    return textwrap.dedent("\n".join(lines[start:end])) + "\n"
