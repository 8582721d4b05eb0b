"""Emulator options: one set, read from a ``sim://`` URL query or from command-line
flags, and turned into a :class:`~snakebot.sim.bus.bus.Bus` of virtual servos.

``sim://[NAME]?robot=snake5&echo=1&corrupt=0.01`` — see :data:`OPTIONS` for the list.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from urllib.parse import parse_qsl, urlencode

from snakebot.errors import quoted
from snakebot.facts import devices
from snakebot.sim.bus.bus import Bus
from snakebot.sim.bus.faults import Brownout, FaultConfig
from snakebot.sim.errors import SimOptionError
from snakebot.sim.servo.fast import VirtualServo

URL_FORM = "sim://[NAME][?robot=NAME|ids=1,2,3][&option=value...]"

OPTIONS: dict[str, str] = {
    "robot": "a built-in robot (snake3, trident, snake5) or a robot TOML file: one servo "
    "per joint, with its ID and model, starting at the joint's zero tick",
    "ids": "comma-separated servo IDs instead of a robot, e.g. 1,2,3 (repeat an ID to "
    "make two servos collide); default 1",
    "model": "servo model, AX-12A or AX-12W (default: the robot's, else AX-12A)",
    "baud": "the servos' baud rate in bit/s (default 1000000); the master's is the port's",
    "return_delay": "the servos' Return Delay Time in microseconds (default 500, the "
    "factory setting; 0 for speed)",
    "echo": "1: the host hears its own instructions, as on a one-wire adapter (default 0)",
    "ideal": "1: servos move instantly to their goal (default 0)",
    "voltage": "supply voltage in volts (default 12)",
    "state": "a file keeping the servos' EEPROM between runs",
    "realtime": "1: tie the bus clock to the wall clock instead of running as fast as "
    "possible (sim:// only; the pty and socket servers always do)",
    "world": "kinematic (default: each servo moves by its own model) or mujoco: the "
    "robot's body in MuJoCo moves the servos, whose position, speed and load come from "
    "the physics (needs robot=)",
    "seed": "seed for every injected fault (default 0)",
    "corrupt": "probability that a byte on the wire gets a flipped bit, e.g. 0.01",
    "drop": "probability that a status packet is never sent",
    "delay": "extra milliseconds before every status packet",
    "jitter": "plus a random 0..jitter milliseconds",
    "noise": "noise bursts per second of bus time",
    "noise_len": "longest noise burst in bytes (default 4)",
    "brownout": "ID@START+DURATION in seconds: that servo loses power (repeatable, or "
    "several separated by ';')",
}

WORLD_PERIOD_S = 0.01
"""How often a physics world behind a sim:// bus samples (its record is not kept)."""

_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"0", "false", "no", "off"}


def _bool(name: str, text: str) -> bool:
    word = text.strip().lower()
    if word in _TRUE:
        return True
    if word in _FALSE:
        return False
    raise SimOptionError(f"option {name}={quoted(text)}: write {name}=1 or {name}=0")


def _number(name: str, text: str, low: float = 0.0, high: float = math.inf) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not low <= value <= high:
        raise SimOptionError(
            f"option {name}={quoted(text)} must be a number from {low:g} to {high:g}"
        )
    return value


def _int(name: str, text: str, low: int, high: int) -> int:
    value = _number(name, text, low, high)
    if value != int(value):
        raise SimOptionError(f"option {name}={quoted(text)} must be a whole number")
    return int(value)


def servo_baud_register(bps: float) -> int:
    """The Baud Rate register value whose rate (the AX-12's baud formula) comes within
    the AX-12's UART tolerance of ``bps``."""
    baud = devices.ax12().require_baud()
    value = baud.value_for(bps)
    if value is not None:
        return value
    raise SimOptionError(
        f"an AX-12 cannot run at {bps:g} bit/s: its rate is {baud.describe()} "
        "(e.g. 1000000 or 57142)"
    )


@dataclass(frozen=True)
class SimOptions:
    """How to build an emulated bus."""

    robot: str | None = None
    ids: tuple[int, ...] | None = None
    model: str | None = None
    servo_baud: float | None = None
    return_delay_us: float | None = None
    echo: bool = False
    ideal: bool = False
    voltage: float | None = None
    state: str | None = None
    realtime: bool = False
    world: str = "kinematic"
    faults: FaultConfig = field(default_factory=FaultConfig)

    @classmethod
    def from_query(cls, query: str) -> SimOptions:
        """Options from a URL query string (``robot=snake5&echo=1``)."""
        opts = cls()
        fault: dict[str, object] = {}
        brownouts: list[Brownout] = []
        try:
            # "+" is literal here (brownout=10@5+1), not the form-encoding of a space.
            pairs = parse_qsl(
                query.replace("+", "%2B"), keep_blank_values=True, strict_parsing=bool(query)
            )
        except ValueError:
            raise SimOptionError(
                f"cannot read the options {quoted(query)}: expected {URL_FORM}"
            ) from None
        for key, value in pairs:
            if key == "robot":
                opts = replace(opts, robot=value)
            elif key == "ids":
                try:
                    ids = tuple(int(v) for v in value.split(",") if v.strip())
                except ValueError:
                    ids = ()
                if not ids or not all(0 <= i <= 253 for i in ids):
                    raise SimOptionError(
                        f"option ids={quoted(value)}: give IDs 0..253, e.g. ids=1,2,3"
                    )
                opts = replace(opts, ids=ids)
            elif key == "model":
                opts = replace(opts, model=value)
            elif key == "baud":
                opts = replace(opts, servo_baud=_number(key, value, 1, 4_000_000))
            elif key == "return_delay":
                opts = replace(opts, return_delay_us=_number(key, value, 0, 508))
            elif key in ("echo", "ideal", "realtime"):
                opts = replace(opts, **{key: _bool(key, value)})
            elif key == "voltage":
                opts = replace(opts, voltage=_number(key, value, 0, 25.5))
            elif key == "state":
                opts = replace(opts, state=value)
            elif key == "world":
                from snakebot.sim.physics.select import check_world

                opts = replace(opts, world=check_world(value))
            elif key == "seed":
                fault["seed"] = _int(key, value, 0, 2**63)
            elif key in ("corrupt", "drop"):
                fault[key] = _number(key, value, 0, 1)
            elif key in ("delay", "jitter"):
                fault[f"{key}_s"] = _number(key, value, 0, 10_000) / 1000
            elif key == "noise":
                fault["noise_rate"] = _number(key, value, 0, 1e6)
            elif key == "noise_len":
                fault["noise_len"] = _int(key, value, 1, 255)
            elif key == "brownout":
                brownouts += [Brownout.parse(v) for v in value.split(";") if v.strip()]
            else:
                raise SimOptionError(
                    f"unknown sim:// option {quoted(key)}: expected {URL_FORM} with options "
                    + ", ".join(OPTIONS)
                )
        if brownouts:
            fault["brownouts"] = tuple(brownouts)
        return replace(opts, faults=FaultConfig(**fault))  # type: ignore[arg-type]

    def servo_layout(self) -> tuple[str, list[tuple[int, float]]]:
        """(model, [(servo ID, start position)]) from the robot or the ID list."""
        if self.robot and self.ids:
            raise SimOptionError("give either a robot or a list of servo IDs, not both")
        if self.robot:
            from snakebot.model.robots import load_robot  # the robot layer is only needed here

            robot = load_robot(self.robot)
            model = self.model or robot.servo_model
            return model, [(j.servo_id, float(j.zero_tick)) for j in robot.joints]
        return self.model or "AX-12A", [(i, 512.0) for i in (self.ids or (1,))]

    def build_bus(self, baudrate: float = 1_000_000) -> Bus:
        """A bus whose master runs at ``baudrate``, with the servos these options describe.

        With a state file that already exists, the servos' EEPROM comes from it, and
        ``baud`` and ``return_delay`` (EEPROM settings) apply only when it is created.
        """
        model, layout = self.servo_layout()
        servos = [VirtualServo(i, model, position=p, ideal=self.ideal) for i, p in layout]
        for s in servos:
            if self.servo_baud is not None:
                s.set_register("Baud Rate", servo_baud_register(self.servo_baud))
            if self.return_delay_us is not None:
                s.set_register("Return Delay Time", round(self.return_delay_us / 2))
        if self.state:
            from snakebot.sim.state import EepromStore

            EepromStore(self.state).attach(servos)
        bus = Bus(
            servos, baudrate=baudrate, echo=self.echo, faults=self.faults, supply_v=self.voltage
        )
        if self.world != "kinematic":
            self._attach_world(bus)
        return bus

    def _attach_world(self, bus: Bus) -> None:
        """Put the robot's body in the physics world on ``bus``: from now on it moves the
        servos (the world lives as long as the bus's schedule of its steps)."""
        if not self.robot:
            raise SimOptionError(f"world={self.world} needs the robot's body: add robot=NAME")
        if self.ideal:
            raise SimOptionError(
                f"ideal servos have no torque: drop ideal=1 for world={self.world}"
            )
        from snakebot.model.robots import load_robot
        from snakebot.sim.physics.select import make_world

        make_world(self.world, bus, load_robot(self.robot), period=WORLD_PERIOD_S, keep=1)


def sim_query(**options: object) -> str:
    """The query of a sim:// URL for ``options`` (the names :meth:`SimOptions.from_query`
    takes): unset ones (None, False, ()) left out, flags as 1, each brownout its own
    pair. ``sim://?`` followed by it is the same emulation in process."""
    pairs: list[tuple[str, str]] = []
    for key, value in options.items():
        if value is None or value is False or value == ():
            continue
        if key == "brownout":
            pairs += [("brownout", v) for v in value]  # type: ignore[union-attr]
        elif value is True:
            pairs.append((key, "1"))
        else:
            pairs.append((key, str(value)))
    return urlencode(pairs, safe=",@+;/")
