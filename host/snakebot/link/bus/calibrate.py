"""Calibrate a robot description against its servos: read each joint's zero tick with
the snake lying straight, jog each joint to confirm its sign, and write the TOML back
with its comments and layout kept (tomlkit), atomically.

The servos are reached through a :class:`~snakebot.link.transport.DxlClient` on a direct
adapter (or the emulator); registers and units come from the AX-12 description.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import tomlkit

from snakebot.facts import devices
from snakebot.formats.register_values import BusCommandError
from snakebot.link.bus.scan import identify
from snakebot.link.transport import DxlClient
from snakebot.model.robots.loader import parse_robot
from snakebot.model.robots.model import Joint, Robot
from snakebot.userfiles import write_atomic

JOG_DEG = 10.0
"""How far each joint is turned to show its direction."""

JOG_SPEED_RPM = 10.0
"""How fast the jog turns (gently: the snake may be lying on a table)."""

ARRIVE_TIMEOUT_S = 3.0
"""How long a jogged servo may take to reach its goal before it counts as stuck."""

_AX12 = devices.ax12()
_TORQUE = _AX12.register("Torque Enable")
_GOAL = _AX12.register("Goal Position")
_SPEED = _AX12.register("Moving Speed")
_PRESENT = _AX12.register("Present Position")
_COMPLIANCE_TICKS = 2
"""How far from its goal a servo may stop (its compliance margin, with a tick spare)."""


@dataclass(frozen=True)
class JointCalibration:
    """What calibration found for one joint."""

    name: str
    servo_id: int
    zero_tick: int
    sign: int
    asked: bool  # the sign came from the user (else: kept from the file)
    moved_ticks: int  # how far the servo turned on its jog

    def as_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "servo_id": self.servo_id,
            "zero_tick": self.zero_tick,
            "sign": self.sign,
            "sign_from": "user" if self.asked else "file",
            "jog_moved_ticks": self.moved_ticks,
        }


Ask = Callable[[Joint], bool]
"""Asked after a joint's jog: did the link nearer the head turn counter-clockwise?"""


def _wait_until_at(client: DxlClient, servo_id: int, goal: int) -> int:
    """Read Present Position back to back (the bus is ours, and on the emulator each
    read is what moves its clock) until the servo is at ``goal`` or the time is up;
    where it is."""
    deadline = time.monotonic() + ARRIVE_TIMEOUT_S
    while True:
        here = client.read_u16(servo_id, _PRESENT.address)
        if abs(here - goal) <= _COMPLIANCE_TICKS or time.monotonic() > deadline:
            return here


def _move(client: DxlClient, servo_id: int, goal: int) -> int:
    client.write(servo_id, _GOAL.address, _GOAL.encode(goal))
    return _wait_until_at(client, servo_id, goal)


def read_zero_ticks(client: DxlClient, robot: Robot) -> dict[int, int]:
    """Torque off every joint and read its position: servo ID -> zero tick."""
    missing = [j.servo_id for j in robot.joints if identify(client, j.servo_id) is None]
    if missing:
        raise BusCommandError(
            f"servo{'s' if len(missing) > 1 else ''} {', '.join(map(str, missing))} of "
            f"{robot.name} do{'' if len(missing) > 1 else 'es'} not answer at "
            f"{client.baudrate} baud: check power and cabling, and the IDs (snakebot bus scan)"
        )
    for joint in robot.joints:
        client.write(joint.servo_id, _TORQUE.address, _TORQUE.encode(0))
    # Confirmed by a second read: the zero tick is saved in the robot file, and a reply
    # damaged within the position range passes the checksum about once in 256.
    return {
        j.servo_id: int.from_bytes(
            client.read_confirmed(j.servo_id, _PRESENT.address, _PRESENT.size), "little"
        )
        for j in robot.joints
    }


def jog(client: DxlClient, joint: Joint, zero_tick: int) -> int:
    """Turn the joint JOG_DEG towards growing ticks and back, torque off after; returns
    how many ticks it turned (negative when there was room only below the zero tick).
    Raises if it did not follow."""
    sid = joint.servo_id
    step = round(JOG_DEG * _AX12.require_position().scale.per_unit("deg"))
    low, high = _AX12.require_position().range
    target = zero_tick + step if zero_tick + step <= high else zero_tick - step
    if target < low:
        raise BusCommandError(f"{joint.name}: no room to jog around tick {zero_tick}")
    client.write(sid, _SPEED.address, _SPEED.encode(_SPEED.from_units(JOG_SPEED_RPM, "rpm")))
    client.write(sid, _GOAL.address, _GOAL.encode(zero_tick))
    client.write(sid, _TORQUE.address, _TORQUE.encode(1))
    try:
        reached = _move(client, sid, target)
        _move(client, sid, zero_tick)
    finally:
        client.write(sid, _TORQUE.address, _TORQUE.encode(0))
    moved = reached - zero_tick
    if abs(moved - (target - zero_tick)) > _COMPLIANCE_TICKS:
        raise BusCommandError(
            f"{joint.name} (servo {sid}) turned {moved} ticks when asked for "
            f"{target - zero_tick}: is it blocked, or its Torque Limit low? Free it and "
            "calibrate again"
        )
    return moved


def calibrate(client: DxlClient, robot: Robot, ask: Ask | None) -> list[JointCalibration]:
    """Zero ticks read now (the snake must already lie straight), and each joint jogged:
    its sign from ``ask`` (True: counter-clockwise, sign +1), or kept from the file if
    ``ask`` is None, the jog then only checking that the servo follows."""
    zeros = read_zero_ticks(client, robot)
    found = []
    for joint in robot.joints:
        zero = zeros[joint.servo_id]
        moved = jog(client, joint, zero)
        sign = joint.sign if ask is None else (1 if ask(joint) else -1)
        found.append(
            JointCalibration(joint.name, joint.servo_id, zero, sign, ask is not None, moved)
        )
    return found


def updated_text(text: str, found: list[JointCalibration]) -> str:
    """The TOML ``text`` with each joint's zero_tick and sign replaced, all else kept;
    RobotError if the result is not a valid robot (e.g. limits that leave 0-1023)."""
    doc = tomlkit.parse(text)
    by_id = {c.servo_id: c for c in found}
    for entry in doc.get("joints", []):
        c = by_id.get(int(entry["servo_id"]))
        if c is not None:
            entry["zero_tick"] = c.zero_tick
            entry["sign"] = c.sign
    out = tomlkit.dumps(doc)
    parse_robot(out, source="calibrated")
    return out


def write_atomically(path: Path, text: str) -> None:
    """Replace ``path`` by ``text`` in one step: a reader sees the old file or the new."""
    write_atomic(path, text)  # keeps the file's mode: a 0644 robot file stays 0644
