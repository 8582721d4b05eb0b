"""What every campaign runs on, on either board: the builds, the three servos, the table on
their limits, the timing allowances, the registers the checks read, and the failure of the
rig itself."""

from __future__ import annotations

import importlib
import sys
from types import ModuleType

import numpy as np

from snakebot.facts import devices
from snakebot.formats.gaittable import GaitTable
from snakebot.formats.protocol import (
    MAX_PACKET_LEN,
)
from snakebot.link.controller import load
from snakebot.paths import REPO_ROOT
from snakebot.sim.errors import SimFailure

BUILD = REPO_ROOT / "build"  # each board's image and ELF below it (`make firmware`)
CORE_DIR = REPO_ROOT / "firmware" / "core"

IDS = (1, 2, 3)
LIMITS = ((300, 724), (320, 700), (300, 724))
FRAMES = np.array([[724, 320, 724], [300, 700, 300], [512, 510, 512], [700, 330, 650]], np.uint16)
PERIOD_MS = 150
STEERING = 150  # ticks added to every goal: half the goals would leave the limits unclamped
CONTROLLER_ID = load().default_id
SAMPLE_S = 0.1  # how often the watch loop looks
STALL_MS = 100  # ten control ticks without a bus packet while the roster is polled
UPTIME_SLACK_MS = 500  # SysTick counts the emulator's time, which never runs ahead of ours
UPTIME_STILL_S = 2.0  # how long the uptime counter may seem to stand still at the start
LOG_TAIL = 2000  # characters of the machine's log in a problem report
REBUILD = "rebuild the firmware with `make firmware` and run again"
CTL = load()
MAX_LEN_FIELD = MAX_PACKET_LEN - 4  # the largest LEN byte a packet can carry
AX12 = devices.ax12()
GOAL_POSITION, GOAL_BLOCK = AX12.span("Goal Position", "Moving Speed")
"""What the firmware's goal SYNC_WRITE sets per servo: Goal Position and Moving Speed."""
TORQUE_ENABLE = AX12.register("Torque Enable").address
_, TELEMETRY_PARAMS = AX12.span("Present Position", "Present Temperature")
"""The telemetry READ's length."""
TELEMETRY_ADDRESS = AX12.register("Present Position").address
"""Where the telemetry READ starts (the firmware also READs angle limits: not telemetry)."""


def _reg(name: str) -> int:
    return CTL.register(name).address


def support(name: str) -> ModuleType:
    """The test support module ``name`` (tests/support/, which pytest puts on the path)."""
    folder = str(REPO_ROOT / "tests" / "support")
    if folder not in sys.path:
        sys.path.insert(0, folder)
    return importlib.import_module(name)


class CampaignFailed(SimFailure):
    """A campaign could not run (not: an invariant failed; that is a result)."""


def gait_table() -> bytes:
    return GaitTable(IDS, PERIOD_MS, True, LIMITS, FRAMES, {"campaign": "limits"}).encode()


def big_table() -> bytes:
    """A second, longer table (ten upload chunks) for the upload campaign."""
    t = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    frames = np.stack([512 + 150 * np.sin(t + k) for k in range(len(IDS))], axis=1)
    return GaitTable(IDS, 40, True, LIMITS, frames.round().astype(np.uint16), {}).encode()
