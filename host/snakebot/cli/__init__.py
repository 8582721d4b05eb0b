"""The ``snakebot`` command line: the top layer, and nothing but a front.

One subpackage per command group with several commands (``bus``, ``controller``,
``gait``, ``sim``) and one module per stand-alone command (``compare``, ``demo``,
``doctor``, ``flash``, ``model``, ``plan``, ``program``, ``robot``); every command is
registered in :data:`COMMANDS` and imported only when it is run (``lazy``). A command
parses its options, calls one operation from the library and prints; ``options``
declares the options that more than one command takes (once), ``params`` holds the
option types, ``output`` the JSON and text writers, ``signals`` the Ctrl-C and hang-up
handling. Errors become one line on stderr and an
exit status: 1 runtime failure, 2 bad input, 130 Ctrl-C (see ``errors``).

May import: every layer of the package (``plots``, ``workflows``, ``sim``, ``link``,
``model``, ``formats``, ``facts``, the package root). Nothing in the package imports
it but ``python -m snakebot``.
"""

from __future__ import annotations

import click

from snakebot import __version__
from snakebot.cli.lazy import LazyCommand, LazyGroup

COMMANDS: dict[str, LazyCommand] = {
    "model": LazyCommand(
        "snakebot.cli.model:model",
        "Kinematic models of a robot: its description, control vector fields, Lie brackets "
        "and controllability (docs/models.md has the conventions).",
    ),
    "gait": LazyCommand(
        "snakebot.cli.gait:gait", "Generate gait tables for the controller, and inspect them."
    ),
    "sim": LazyCommand(
        "snakebot.cli.sim:sim",
        "The emulated robot: virtual AX-12 servos on an emulated bus.",
        (
            "snakebot.cli.sim.predict:predict",
            "snakebot.cli.sim.serve:serve",
            "snakebot.cli.sim.bootloader:bootloader",
            "snakebot.cli.sim.goto:goto",
            "snakebot.cli.sim.thesis:thesis",
            "snakebot.cli.sim.thesis:friction",
            "snakebot.cli.sim.view:view",
        ),
    ),
    "upload": LazyCommand(
        "snakebot.cli.controller.upload:upload",
        "Upload the gait table GAIT (a .gait file from `snakebot gait`) to the controller, or "
        "a program (a .prog file from `snakebot program build`), which takes the table's "
        "place; `snakebot play` then runs whichever is active.",
    ),
    "limits": LazyCommand(
        "snakebot.cli.controller.limits:limits",
        "The robot's joint limits, kept by the controller and enforced by the servos.",
    ),
    "play": LazyCommand(
        "snakebot.cli.controller.playback:play",
        "Play the controller's gait table from its first frame, or run its program.",
    ),
    "stop": LazyCommand(
        "snakebot.cli.controller.playback:stop",
        "Stop the controller's gait; the servos hold their last position.",
    ),
    "serpenoid": LazyCommand(
        "snakebot.cli.controller.playback:serpenoid",
        "Run the serpenoid gait computed on line by the controller's firmware:",
    ),
    "monitor": LazyCommand(
        "snakebot.cli.controller.monitor:monitor",
        "Show the controller's state and error flags, and each roster servo's position, "
        "load, voltage, temperature and errors, as the controller last read them.",
    ),
    "bus": LazyCommand(
        "snakebot.cli.bus:bus",
        "Servo chores on a Dynamixel bus: find servos, read and write their registers by "
        "name, change an ID or a baud rate.",
        ("snakebot.cli.bus.play:bus_play",),
    ),
    "flash": LazyCommand(
        "snakebot.cli.flash:flash_command",
        "Flash FIRMWARE (a .bin, .hex or .elf) onto the CM-530 through its ROBOTIS bootloader.",
    ),
    "demo": LazyCommand(
        "snakebot.cli.demo:demo",
        "Run the whole chain on the emulated 5-link robot and report what it did.",
    ),
    "plan": LazyCommand(
        "snakebot.cli.plan:plan_command",
        "Plan a gait table that takes ROBOT (snake3, trident, snake5 or a .toml) from rest to "
        "a target pose, for `snakebot upload` and `play`.",
    ),
    "robot": LazyCommand(
        "snakebot.cli.robot:robot",
        "Work on a robot description (a robot .toml): start one, calibrate it against the "
        "real robot, or export it for other tools.",
    ),
    "drive": LazyCommand(
        "snakebot.cli.controller.drive:drive",
        "Run the controller's serpenoid and steer it live.",
    ),
    "program": LazyCommand(
        "snakebot.cli.program:program",
        "Controller programs: up to 64 segments (play table frames, run the serpenoid, run a "
        "periodic input) the controller runs one after the other, each starting where the "
        "previous one was heading (protocol/program.md).",
    ),
    "config": LazyCommand(
        "snakebot.cli.controller.config:config", "Show or change the controller's settings."
    ),
    "doctor": LazyCommand(
        "snakebot.cli.doctor:doctor", "Check a robot's wiring and settings before a first run."
    ),
    "compare": LazyCommand(
        "snakebot.cli.compare:compare_command",
        "Line up RUN (snakebot monitor --csv or --mcap output) against GAIT (the table that was "
        "played) and report how far each joint was from the prediction.",
    ),
    "foxglove-layout": LazyCommand(
        "snakebot.cli.foxglove_layout:foxglove_layout",
        "Write the Foxglove layout for the robot live (--foxglove) and its recordings (--mcap).",
    ),
    "library": LazyCommand(
        "snakebot.cli.controller.library:library",
        "The gait library: named gait tables kept in the controller's flash, in slots that "
        "survive power-off, so the robot can walk without a PC: on the CM-530, U and D pick a "
        "slot (the AUX, MANAGE and PROGRAM LEDs show its number in binary) and START plays it "
        "or stops.",
    ),
}
"""Every command: where it lives, its line in `snakebot --help` (the first sentence of
its help, which tests/cli/test_startup.py holds it to) and, for a group, the sub-commands
kept in modules of their own. Each is imported when it is run (``cli.lazy``)."""


@click.group(
    cls=LazyGroup,
    lazy=COMMANDS,
    context_settings={"help_option_names": ["-h", "--help"]},
)
@click.version_option(__version__, prog_name="snakebot")
def main() -> None:
    """snakebot: derive gaits for wheeled snake robots, check them, and run them on a
    ROBOTIS CM-530 with AX-12 servos, or on the emulated robot.

    Start with `snakebot COMMAND --help`. Ports may be device paths (/dev/ttyUSB0) or
    pyserial URLs. The bus commands also take sim:// (emulated servos, in process); the
    controller commands need the emulated controller of `snakebot sim serve`.
    """
