"""The robot's limits on the controller (protocol/controller.md, "The robot's limits").

    report = set_limits(ctl, robot_limits(load_robot("snake5")))

The controller keeps, per servo ID, the range of position ticks the robot's joint may
reach. They are configuration of the robot, not of a gait table: the firmware makes
every covered servo's CW/CCW Angle Limit equal to them (so the servo itself refuses a
goal outside, whatever the bus does to the packet), refuses tables that reach beyond
them, and refuses to move until the servos are known to hold them.

A robot may also set one Torque Limit for all its servos (``[limits] torque`` in its
file): the firmware holds every covered servo's Torque Limit to it the same way, and
writes it again when a servo's power cycle resets it to Max Torque.

They travel like a table: staged through Upload Data, then committed with Upload Commit
LIMITS; the staged bytes are a count, then one record per servo, then (if set) the
Torque Limit.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

from snakebot.errors import InputError, RuntimeFailure
from snakebot.formats.upload_writes import chunk_writes, commit_write
from snakebot.link.controller import messages as words
from snakebot.link.controller.client import ControllerClient
from snakebot.link.controller.errors import ControllerError
from snakebot.model.robots import Robot
from snakebot.model.robots.model import TORQUE_LIMIT

RECORD = struct.Struct("<BHH")
"""One servo's limits as staged: servo ID, min tick, max tick."""

VERIFY_TIMEOUT_S = 10.0
"""How long the servos may take to be read, written and read back (a few control ticks
each; generous for a slow emulator)."""

Limits = Mapping[int, tuple[int, int]]


class LimitsError(ControllerError):
    """The controller refused the robot's limits, or its servos did not take them (the
    base of the two below)."""


class LimitsRefused(LimitsError, InputError):
    """The controller refused the robot's limits as malformed."""


class LimitsFailed(LimitsError, RuntimeFailure):
    """The servos did not take the robot's limits (one did not answer, or keeps Lock set),
    or the controller was busy."""


def robot_limits(robot: Robot) -> dict[int, tuple[int, int]]:
    """Servo ID -> (min tick, max tick) of each joint of ``robot``."""
    return dict(zip(robot.servo_ids, robot.tick_limits, strict=True))


def encode_limits(limits: Limits, torque: int | None = None) -> bytes:
    """The staged form: the servo count, then a :data:`RECORD` per servo, then the raw
    Torque Limit (the servo register's size, little-endian) when ``torque`` is given."""
    blob = bytes([len(limits)]) + b"".join(
        RECORD.pack(sid, lo, hi) for sid, (lo, hi) in sorted(limits.items())
    )
    return blob if torque is None else blob + torque.to_bytes(TORQUE_LIMIT.size, "little")


def torque_text(torque: int | None) -> str:
    """A raw Torque Limit in the servo's unit ("60% of stall torque (614)")."""
    if torque is None:
        return "none (the servos keep their own)"
    unit = TORQUE_LIMIT.scale.unit if TORQUE_LIMIT.scale is not None else ""
    return f"{TORQUE_LIMIT.to_units(torque):.3g}{unit} ({torque})"


@dataclass
class LimitsReport:
    """What the controller says after the limits were set."""

    limits: dict[int, tuple[int, int]]
    state: str
    count: int
    seconds: float
    error_flags: list[str] = field(default_factory=list)
    torque_limit: int | None = None  # raw Torque Limit; None: not set

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["limits"] = {str(k): list(v) for k, v in self.limits.items()}
        d.update(torque_fields(self.torque_limit))
        return d

    def summary(self) -> str:
        servos = ", ".join(f"{sid}: {lo}..{hi}" for sid, (lo, hi) in sorted(self.limits.items()))
        held = "angle limits" if self.torque_limit is None else "angle and torque limits"
        return (
            f"robot limits set for {self.count} servos ({servos}; torque limit "
            f"{torque_text(self.torque_limit)}); the servos' {held} are {self.state} after "
            f"{self.seconds:.1f} s"
        )


def _state_name(ctl: ControllerClient, value: int) -> str:
    for name, code in ctl.table.enums["Limits State"].items():
        if code == value:
            return name
    return f"UNKNOWN({value})"


def limits_state(ctl: ControllerClient) -> tuple[str, int]:
    """(Limits State by name, Limits Count)."""
    r = ctl.read("Limits Count", "Limits State")
    return _state_name(ctl, r["Limits State"]), r["Limits Count"]


def robot_torque_limit(ctl: ControllerClient) -> int | None:
    """The raw Torque Limit the controller holds its servos to (Limits page), or None."""
    register = ctl.table.register("Robot Torque Limit")
    value = ctl.read(register.name)[register.name]
    return None if value == register.default else value


def torque_fields(torque: int | None) -> dict[str, Any]:
    """The torque limit for --json: raw, and in the servo's unit (% of stall torque)."""
    percent = None if torque is None else TORQUE_LIMIT.to_units(torque)
    return {"torque_limit": torque, "torque_limit_percent": percent}


def wait_settled(ctl: ControllerClient, timeout_s: float = VERIFY_TIMEOUT_S) -> tuple[str, int]:
    """Wait while the controller checks its servos' angle limits (Limits State APPLYING),
    at most ``timeout_s``; then (Limits State, Limits Count)."""
    deadline = time.monotonic() + timeout_s
    while True:
        state, count = limits_state(ctl)
        if state != "APPLYING" or time.monotonic() > deadline:
            return state, count
        time.sleep(0.05)


def not_held(ctl: ControllerClient, state: str, timeout_s: float) -> str:
    """Why the servos do not hold the robot's limits, and what to do."""
    flags = ctl.read("Error Flags")["Error Flags"]
    return (
        f"the servos' angle limits are {state} after {timeout_s:.0f} s: a servo did not "
        "answer, or would not store them (Lock is set until it is power-cycled); check "
        "the servos' power, cables and IDs (`snakebot bus scan`), then send CLEAR "
        "(`snakebot stop --clear`) or set the limits again (Error Flags: "
        f"{words.describe_flags(flags, ctl.table)})"
    )


def set_limits(
    ctl: ControllerClient,
    limits: Limits,
    *,
    torque: int | None = None,
    timeout_s: float = VERIFY_TIMEOUT_S,
) -> LimitsReport:
    """Make ``limits`` (and the robot-wide raw Torque Limit ``torque``, if given) the
    controller's robot limits and wait until its servos hold them (Limits State
    VERIFIED). Stops any motion. Raises :class:`LimitsError` with the reason and the fix."""
    t0 = time.monotonic()
    blob = encode_limits(limits, torque)
    for address, data in chunk_writes(blob, controller=ctl.table):
        ctl.write_block(address, data)
    ctl.write_block(*commit_write(blob, ctl.table, what="LIMITS"))
    result = ctl.read("Upload Result")["Upload Result"]
    if result != ctl.table.enums["Upload Result"]["OK"]:
        name, what, fix = words.upload_result_reason(result, ctl.table)
        refused = LimitsFailed if words.is_runtime_result(name) else LimitsRefused
        raise refused(f"the controller refused the robot's limits ({name}: {what}): {fix}")
    state, count = wait_settled(ctl, timeout_s)
    flags = ctl.read("Error Flags")["Error Flags"]
    if state != "VERIFIED":
        raise LimitsFailed(not_held(ctl, state, timeout_s))
    return LimitsReport(
        dict(limits),
        state,
        count,
        time.monotonic() - t0,
        words.flag_names(flags, ctl.table),
        torque,
    )
