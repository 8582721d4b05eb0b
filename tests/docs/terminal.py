"""Running a line that reads the keyboard (`snakebot drive` without ``--keys``) as a reader
does: in a real terminal (tmux), its port replaced by the emulated controller's (a
pseudo-terminal of the test's process), its Foxglove port by a free one
(tests/docs/runnable.py). The screen must show the serpenoid started on the robot's
joints, a left arrow must steer (on screen and in the controller's registers), q must stop
the robot and quit with exit status 0; with ``--foxglove``, a real Foxglove client must
get /joint_states meanwhile."""

from __future__ import annotations

import math
import shlex
from pathlib import Path

from runnable import SNAKEBOT, Emulators, Line, arguments
from stopping import Job, LiveRunner
from tmux_support import Tmux, joints

from snakebot.cli.options import ControllerLink
from snakebot.link.controller.drive import STEER_STEP


class Screen(LiveRunner):
    """The terminal's screen, read as a running command's output is
    (:meth:`LiveRunner.wait`), for the Foxglove client's wait."""

    def __init__(self, tmux: Tmux) -> None:
        super().__init__()
        self.tmux = tmux

    def printed(self) -> str:
        return self.tmux.screen()


def drive(line: Line, emulators: Emulators, folder: Path) -> list[str]:
    """Run ``line`` (a `drive` that reads the keyboard) in tmux in ``folder``: the
    problems found."""
    args, env = arguments(line.commands[0], emulators)
    words = [*(f"{k}={v}" for k, v in env.items()), SNAKEBOT, *args]
    job = Job(emulators.foxglove)
    job.start()
    tmux = Tmux(f"{shlex.join(words)}; echo EXIT=$?; sleep 60", str(folder))
    screen = Screen(tmux)
    steered = f"steering {math.degrees(STEER_STEP):+.1f} deg"
    try:
        screen.wait(lambda: "State SERPENOID" in (s := tmux.screen()) and joints(s), "joints")
        job.ready(screen)
        tmux.keys("Left")
        screen.wait(lambda: steered in tmux.screen(), steered)
        tmux.keys("q")
        end = screen.wait(lambda: "EXIT=" in (s := tmux.screen()) and s, "the end")
        exit_line = next(s for s in end.splitlines() if s.startswith("EXIT="))
        if "Traceback" in end:
            exit_line += " after a traceback"
    except AssertionError as exc:
        return [f"{line.where}: `{line.text}` in a terminal: {exc}"]
    finally:
        tmux.close()
        if job.listener is not None:
            job.listener.stop()
    port = args[args.index("--port") + 1]
    with ControllerLink(port).open() as ctl:
        regs = ctl.read("State", "Steering Offset")
        idle = ctl.table.enums["State"]["IDLE"]
        steering = ctl.table.register("Steering Offset").from_units(STEER_STEP, "rad")
    if exit_line != "EXIT=0" or regs != {"State": idle, "Steering Offset": steering}:
        return [
            f"{line.where}: `{line.text}` in a terminal: {exit_line}, then the controller's "
            f"registers {regs} (IDLE, one left step of steering expected)"
        ]
    return []
