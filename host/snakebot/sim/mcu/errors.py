"""What the emulated STM32F103 reports when the firmware does something the chip would not
take, or the emulator does not model."""

from __future__ import annotations

from snakebot.errors import InputError, RuntimeFailure
from snakebot.sim.errors import SimError


class McuError(SimError):
    """The emulated microcontroller could not be set up or run as asked (the area's base:
    each concrete error is an input error or a runtime failure)."""


class McuMisuse(McuError, InputError):
    """The emulator was asked to do something it cannot (e.g. start twice)."""


class McuFault(McuError, RuntimeFailure):
    """The firmware did what a real STM32F103 would fault on, hang on or silently get wrong
    (a fetch from nowhere, an undefined instruction, a rule of the reference manual broken):
    the message names the address and what happened."""


class UnmodelledAccess(McuFault):
    """The firmware touched a register (or a field) the emulator does not model. In strict
    mode (tests) this stops the run, so a firmware change that starts using a new register
    fails loudly instead of reading zeros."""


class ImageError(McuError, InputError):
    """The image cannot run on the emulated CM-530 (another board's, empty, truncated, a
    reset vector outside flash): the message says which and how to fix it."""
