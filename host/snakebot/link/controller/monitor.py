"""Telemetry from the controller: its state and counters, and what it last heard from
each roster servo (the servo window), as records and as a text table.

    s = sample(ctl)                 # one READ of the registers, one per page of 6 servos
    print("\\n".join(render(s)))
    json.dumps(s.as_record())
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

from snakebot.facts.controller import Controller, load
from snakebot.formats.live_topics import JointSample
from snakebot.link.controller import messages as words
from snakebot.link.controller.client import ControllerClient, JointRecord
from snakebot.model.robots.model import Joint, joint_name

# The servo window mirrors the servos' registers: units and encodings are theirs.
_SPEED = load().servo_field("Present Speed")
_LOAD = load().servo_field("Present Load")
_VOLTAGE = load().servo_field("Present Voltage")


@dataclass(frozen=True)
class Sample:
    """One look at the controller: ``t`` seconds since monitoring began."""

    t: float
    registers: dict[str, int]
    servos: list[JointRecord]
    table: Controller

    def controller_record(self) -> dict[str, Any]:
        r = self.registers
        return {
            "state": words.state_name(r["State"], self.table),
            "error_flags": words.flag_names(r["Error Flags"], self.table),
            "play_frame": r["Play Frame"],
            "speed": r["Speed Scale"] / 256,
            "steering_offset_ticks": r["Steering Offset"],
            "loop": bool(r["Loop"]),
            "joint_count": r["Joint Count"],
            "table_bytes": r["Table Size"],
            "table_crc": f"0x{r['Table CRC']:08x}",
            "table_frames": r["Table Frames"],
            "table_period_ms": r["Table Period"],
            "pc_packets": r["PC Packets"],
            "pc_errors": r["PC Errors"],
            "bus_reads": r["Bus Reads"],
            "bus_timeouts": r["Bus Timeouts"],
            "bus_errors": r["Bus Errors"],
        }

    def as_record(self) -> dict[str, Any]:
        """One JSON Lines record."""
        return {
            "t": round(self.t, 3),
            "controller": self.controller_record(),
            "servos": [servo_record(j) for j in self.servos],
        }


def joint_of(j: JointRecord) -> Joint:
    """The roster joint as a robot joint, for its tick-to-angle conversion (the limits
    play no part in it)."""
    return Joint(joint_name(j.joint), j.id, j.zero_tick, -1 if j.reverse else 1, 0.0, 0.0)


def servo_record(j: JointRecord) -> dict[str, Any]:
    joint = joint_of(j)
    return {
        "joint": j.joint,
        "name": joint.name,
        "id": j.id,
        "goal": j.goal,
        "goal_deg": round(math.degrees(joint.tick_to_angle(j.goal)), 2),
        "position": j.position,
        "position_deg": round(math.degrees(joint.tick_to_angle(j.position)), 2),
        "speed_rpm": round(_SPEED.to_units(j.speed, "rpm"), 2),
        "load": _LOAD.value(j.load),
        "load_percent": round(_LOAD.to_units(j.load), 1),
        "voltage_v": round(_VOLTAGE.to_units(j.voltage, "V"), 1),
        "temperature_c": j.temperature,
        "error": words.servo_error_names(j.error),
        "error_count": j.error_count,
        "timeout_count": j.timeout_count,
        "reverse": bool(j.reverse),
        "zero_tick": j.zero_tick,
        "min_tick": j.min_tick,
        "max_tick": j.max_tick,
    }


def joint_sample(s: Sample) -> JointSample:
    """The roster's joints in a sample as the live topics carry them: angles in radians,
    speeds in rad/s and loads (a fraction of the stall torque) in each joint's own
    direction, the servos' error flags."""
    names, goal, present, velocity, load, errors = [], [], [], [], [], []
    for j in s.servos:
        joint = joint_of(j)
        names.append(joint.name)
        goal.append(joint.tick_to_angle(j.goal))
        present.append(joint.tick_to_angle(j.position))
        velocity.append(joint.sign * _SPEED.to_units(j.speed, "rad/s"))
        load.append(joint.sign * _LOAD.to_units(j.load) / 100.0)  # percent: + counter-clockwise
        errors.append(int(j.error))
    return JointSample(names, goal, present, velocity, load, errors)


def sample(ctl: ControllerClient, t0: float | None = None) -> Sample:
    """Read the controller's registers and its roster's mirror."""
    now = time.monotonic()
    registers = ctl.read_all()
    servos = ctl.roster(registers["Joint Count"])
    return Sample(now - (now if t0 is None else t0), registers, servos, ctl.table)


CSV_COLUMNS = (
    "t",
    "frame",
    "state",
    "name",
    "id",
    "goal",
    "goal_deg",
    "position",
    "position_deg",
    "speed_rpm",
    "load_percent",
    "voltage_v",
    "temperature_c",
    "error",
)
"""The columns of ``snakebot monitor --csv``: one row per roster servo per sample."""


def csv_rows(s: Sample) -> list[dict[str, Any]]:
    """The sample as CSV rows (:data:`CSV_COLUMNS`), one per roster servo."""
    c = s.controller_record()
    # frame: the controller's own clock, the table frame it was playing (Play Frame)
    base = {"t": round(s.t, 3), "frame": c["play_frame"], "state": c["state"]}
    rows = []
    for j in s.servos:
        record = servo_record(j)
        record["error"] = " ".join(record["error"])
        rows.append(base | {k: record[k] for k in CSV_COLUMNS if k in record})
    return rows


HEADER = (
    f"{'joint':>5} {'ID':>4} {'goal':>5} {'pos':>5} {'angle':>9} {'speed':>10} {'load':>7} "
    f"{'volt':>5} {'temp':>5}  errors"
)
UNITS = (
    f"{'':>5} {'':>4} {'tick':>5} {'tick':>5} {'deg':>9} {'rpm':>10} {'%':>7} {'V':>5} {'degC':>5}"
)
"""The servo table's column names, and their units on the line below."""


def render(s: Sample) -> list[str]:
    """The sample as lines of text: the controller's line, then one line per servo."""
    c = s.controller_record()
    flags = words.describe_flags(s.registers["Error Flags"], s.table)
    lines = [
        f"t = {s.t:7.2f} s   state {c['state']}   frame {c['play_frame']}   "
        f"speed {c['speed']:.2f}x   table {c['table_bytes']} bytes, file CRC-32 {c['table_crc']}",
        f"error flags: {flags}",
        f"PC link: {c['pc_packets']} packets, {c['pc_errors']} damaged   bus: "
        f"{c['bus_reads']} reads, {c['bus_timeouts']} timeouts, {c['bus_errors']} damaged",
    ]
    if not s.servos:
        lines.append(
            "no servos in the roster (upload a gait table, or start the serpenoid for a robot)"
        )
        return lines
    lines += [HEADER, UNITS]
    for j in s.servos:
        r = servo_record(j)
        errors = words.servo_error_words(j.error)
        if j.timeout_count:
            errors += f"; {j.timeout_count} reads unanswered"
        if j.error_count:
            errors += f"; {j.error_count} replies with errors"
        lines.append(
            f"{r['name']:>5} {j.id:>4} {j.goal:>5} {j.position:>5} {r['position_deg']:>+9.1f} "
            f"{r['speed_rpm']:>10.1f} "
            f"{r['load_percent']:>7.1f} {r['voltage_v']:>5.1f} {j.temperature:>5}  {errors}"
        )
    return lines
