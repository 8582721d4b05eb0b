"""Driving the controller's on-board serpenoid live: keys turn, change speed, stop and
start; a look at the controller shows the joints (degrees), load, error flags and state.
A program the controller is running already (``snakebot play`` of a .prog) is driven
instead of the serpenoid: the same keys steer its serpenoid segments and run it faster or
slower.

    driver = Driver(ctl, settings, roster=roster_from_robot(robot))
    driver.start()                      # the serpenoid runs
    event = driver.press("left")        # steer left: Steering Offset changes
    view = driver.look()                # state, flags, joints
    driver.press("q")                   # stop the robot and quit

The firmware slews every live change (protocol/controller.md), so a key press never
steps a goal further than a servo follows in one control tick. Keys come from a terminal
(:func:`read_key`) or from a script (:func:`parse_keys`), handled alike.
"""

from __future__ import annotations

import math
import os
import re
import select
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from snakebot.errors import quoted
from snakebot.formats.protocol import ErrorFlags
from snakebot.link.controller import messages as words
from snakebot.link.controller import playback
from snakebot.link.controller.client import ControllerClient, RosterEntry
from snakebot.link.controller.errors import ControllerError, ControllerLinkError, ControllerRefused
from snakebot.link.controller.monitor import Sample, sample, servo_record

STEER_STEP = math.radians(5)
"""How far one left/right press turns: radians of Steering Offset."""
SPEED_STEP = 0.25
"""How much one up/down press changes the speed factor."""

ACTIONS = {
    "left": "steer left",
    "right": "steer right",
    "up": "faster",
    "down": "slower",
    "space": "stop or start",
    "q": "stop and quit",
}
"""The keys and what they do."""

# Script tokens: full names, or a run of the letters L, R, U, D ("LLRR" is four presses).
_LETTERS = {"L": "left", "R": "right", "U": "up", "D": "down"}
_NAMES = {"left": "left", "right": "right", "up": "up", "down": "down", "space": "space"}
_NAMES |= {"q": "q", "quit": "q"}
_WAIT = re.compile(r"^(\d+(?:\.\d*)?|\.\d+)s$")
MAX_WAIT_S = 600.0
"""The longest wait a script may ask for at once."""

# Terminal escape sequences of the arrow keys (ANSI, as xterm, tmux and Linux send them).
_ARROWS = {"\x1b[A": "up", "\x1b[B": "down", "\x1b[C": "right", "\x1b[D": "left"}
_ARROWS |= {"\x1bOA": "up", "\x1bOB": "down", "\x1bOC": "right", "\x1bOD": "left"}


@dataclass(frozen=True)
class Wait:
    """A pause in a script, seconds."""

    seconds: float


def parse_keys(text: str) -> list[str | Wait]:
    """The key presses (names of :data:`ACTIONS`) and waits in a script: tokens separated
    by blanks or new lines, ``#`` to the end of a line a comment. A token is a key name
    (left, right, up, down, space, q), a run of the letters L R U D, or a wait such as
    ``0.5s``. ValueError names the first token that is none of these."""
    keys: list[str | Wait] = []
    for line in text.splitlines():
        for token in line.split("#", 1)[0].split():
            keys.extend(_token(token))
    return keys


def _token(token: str) -> list[str | Wait]:
    if token.lower() in _NAMES:
        return [_NAMES[token.lower()]]
    if set(token) <= set(_LETTERS):
        return [_LETTERS[c] for c in token]
    wait = _WAIT.match(token)
    if wait:
        seconds = float(wait.group(1))
        if seconds > MAX_WAIT_S:
            raise ValueError(f"wait {token} is longer than {MAX_WAIT_S:g}s: split it")
        return [Wait(seconds)]
    raise ValueError(
        f"unknown key {quoted(token)}: use left, right, up, down (or the letters L R U D), "
        "space, q, or a wait such as 0.5s"
    )


def read_key(fd: int, timeout: float) -> str | None:
    """The next key pressed on terminal ``fd`` (in cbreak mode) within ``timeout``
    seconds: a name of :data:`ACTIONS`, "" for any other key, None if none came."""
    ready, _, _ = select.select([fd], [], [], timeout)
    if not ready:
        return None
    data = os.read(fd, 1).decode(errors="replace")
    if data == "\x1b":  # an escape sequence arrives whole, or it is a lone Escape
        while len(data) < 3 and select.select([fd], [], [], 0.05)[0]:
            data += os.read(fd, 1).decode(errors="replace")
    if data in _ARROWS:
        return _ARROWS[data]
    if data == " ":
        return "space"
    if data.lower() == "q":
        return "q"
    return ""


@dataclass
class Driver:
    """The keys' effect on the controller at ``ctl``: the serpenoid of ``settings``
    (on ``roster`` if given, else on the controller's own), steered by Steering Offset
    and sped by Speed Scale."""

    ctl: ControllerClient
    settings: playback.SerpenoidSettings
    roster: list[RosterEntry] | None = None
    speed: float = 1.0
    steer: float = 0.0
    on_sample: Callable[[Sample], None] | None = None
    """Called with each look's telemetry sample (a live view's feed)."""
    quit: bool = field(default=False, init=False)

    program: bool = field(default=False, init=False)
    t0: float = field(default_factory=time.monotonic, init=False)

    def start(self) -> dict[str, Any]:
        """Start (or restart) the serpenoid with the current speed and steering; a
        program the controller is running already is steered instead (the controller
        applies Speed Scale to all its segments and Steering Offset to its serpenoid
        ones, protocol/program.md), and restarted by a later start."""
        if self.program or self._program_running():
            self.program = True
            self._set("Speed Scale", "speed", self.speed, playback.SPEED)
            self._set("Steering Offset", "steer", self.steer, "rad")
            if not self.running():
                self.ctl.command("PROGRAM_RUN")
            return {"program": True}
        status = playback.serpenoid(
            self.ctl, self.settings, speed=self.speed, steer=self.steer, roster=self.roster
        )
        self.roster = None  # set once
        return status

    def _program_running(self) -> bool:
        state = self.ctl.read("Program State")["Program State"]
        return bool(state == self.ctl.table.enums["Program State"]["RUNNING"])

    def running(self) -> bool:
        state = words.state_name(self.ctl.read("State")["State"], self.ctl.table)
        return state == ("PLAYING" if self.program else "SERPENOID")

    def press(self, key: str) -> dict[str, Any]:
        """Do what ``key`` (a name of :data:`ACTIONS`) does; returns what was done."""
        done = ACTIONS.get(key, "nothing")
        if key in ("left", "right"):
            step = STEER_STEP if key == "left" else -STEER_STEP
            done = self._set("Steering Offset", "steer", self.steer + step, "rad") or done
        elif key in ("up", "down"):
            step = SPEED_STEP if key == "up" else -SPEED_STEP
            done = self._set("Speed Scale", "speed", self.speed + step, playback.SPEED) or done
        elif key == "space":
            if self.running():
                self.ctl.command("STOP")
                done = "stopped"
            else:
                self.start()
                done = "started"
        elif key == "q":
            self.ctl.command("STOP")
            self.quit = True
            done = "stopped, quit"
        return {
            "key": key,
            "done": done,
            "steer_deg": round(math.degrees(self.steer), 3),
            "speed": self.speed,
        }

    def _set(self, register: str, attr: str, value: float, unit: str) -> str | None:
        """Write ``value`` (in ``unit``) to ``register`` and keep it in ``attr``; at the
        end of the register's range, or if the controller refuses the value, nothing
        changes and the reason is returned."""
        reg = self.ctl.table.register(register)
        raw = reg.from_units(value, unit)
        low, high = reg.value_range()
        if not reg.accepts(raw):
            return f"at the end of the range ({register} {low}..{high})"
        try:
            self.ctl.write({register: raw})
        except ControllerLinkError:
            raise
        except ControllerError as exc:  # the controller's own checks said no: keep driving
            if not isinstance(exc, ControllerRefused) or not exc.flags & ErrorFlags.RANGE:
                return f"refused: {exc}"
            name, _ = playback.refusal_reason(self.ctl)
            # RANGE from a register inside its range: the running wave would leave a
            # joint's limits or pass the servo's speed (the controller's validation)
            return f"at the end of what the joints allow ({register}: Refusal Reason {name})"
        setattr(self, attr, reg.to_units(raw, unit))
        return None

    def look(self) -> dict[str, Any]:
        """The controller's state, error flags, speed and steering, and per roster joint
        its name, goal and position in degrees, load (percent) and errors."""
        s = sample(self.ctl, self.t0)
        if self.on_sample is not None:
            self.on_sample(s)
        c = s.controller_record()
        steering = self.ctl.table.register("Steering Offset")
        steer = steering.to_units(s.registers["Steering Offset"], "rad")
        keep = ("name", "id", "goal_deg", "position_deg", "load_percent", "error")
        return {
            "state": c["state"],
            "error_flags": c["error_flags"],
            "speed": c["speed"],
            "steer_deg": round(math.degrees(steer), 3),
            "joints": [{k: servo_record(j)[k] for k in keep} for j in s.servos],
        }
