"""Every device on a snakebot bus, described once.

Each device (the AX-12A and its variants, the MX series, the snakebot controller) is one
JSON file in ``snakebot/facts/devices/data``: registers with address, size, access, write
range, default, a scale (unit and factor) and an encoding, and device facts (model
number, where Status Return Level lives, the baud formula, the position range). Python
reads them here; ``protocol/gen_headers.py`` writes the firmware's C headers from the
same files. Nothing else types a register address or a unit factor.

    >>> from snakebot.facts import devices
    >>> ax = devices.load("AX-12A")
    >>> ax.register("Goal Position").address
    30
    >>> round(ax.register("Present Speed").to_units(1024 + 100, "rpm"), 1)
    -11.1

May import: the package root only (as ``facts``).
"""

from __future__ import annotations

from snakebot.facts.devices.device import Baud, Device, Page, Position, ServoWindow
from snakebot.facts.devices.errors import DeviceError
from snakebot.facts.devices.loader import by_model_number, load, names, source
from snakebot.facts.devices.register import Register
from snakebot.facts.devices.units import Encoding, Scale, conversion

AX12 = "AX-12A"
"""The servo snakebot robots are built from (the firmware's servo model)."""

CONTROLLER = "controller"
"""The snakebot controller (the CM-530 firmware on the PC link)."""


def ax12() -> Device:
    """The AX-12A."""
    return load(AX12)


def controller() -> Device:
    """The snakebot controller."""
    return load(CONTROLLER)


__all__ = [
    "AX12",
    "CONTROLLER",
    "Baud",
    "Device",
    "DeviceError",
    "Encoding",
    "Page",
    "Position",
    "Register",
    "Scale",
    "ServoWindow",
    "ax12",
    "by_model_number",
    "controller",
    "conversion",
    "load",
    "names",
    "source",
]
