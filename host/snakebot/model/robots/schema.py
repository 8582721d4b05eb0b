"""What each key of a robot file means, with its physical unit: written once, here.

The loader refuses keys that are not in :data:`TABLES` (``SCHEMA`` is derived from it),
and ``snakebot robot new`` writes each meaning as the comment above its key, so a file
and the rules it is read by cannot drift apart.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import snakebot.model.robots.model as rm

MAX_LINKS = 16  # the C core's fixed buffers (KIN_MAX_LINKS)
MAX_SERVO_ID = 253  # 254 is the broadcast ID

LENGTH = "in the robot's length unit (metres when [physics] unit_m is 1)"
_TORQUE_UNIT = rm.TORQUE_LIMIT.scale.unit if rm.TORQUE_LIMIT.scale is not None else "%"
_MODELS = " or ".join(f'"{m}"' for m in rm.SERVO_MAX_RPM)


@dataclass(frozen=True)
class Key:
    """One key: what it means, with its unit and range; ``example`` is the value shown
    (commented out) when a file leaves this optional key out (None: not optional)."""

    meaning: str
    example: Any = None


@dataclass(frozen=True)
class Table:
    """A table of a robot file (``""``: the top level), or an array of tables."""

    meaning: str
    keys: dict[str, Key] = field(default_factory=dict)
    array: bool = False
    optional: bool = False


TABLES: dict[str, Table] = {
    "": Table(
        "",
        {
            "name": Key("the robot's name, as reports print it"),
            "kind": Key(
                '"snake" (a chain of links, a wheel at each link\'s middle), "trident" '
                '(a base with three arms) or "car" (the thesis\'s first chapter)'
            ),
            "description": Key("one line about the robot (optional)", ""),
        },
    ),
    "geometry": Table(
        f"The robot's shape; lengths {LENGTH}. A snake has links and half_link, a "
        "trident base_radius, arm_length and alphas_deg, a car wheelbase.",
        {
            "links": Key(f"snake: how many links (2 to {MAX_LINKS}); it has one joint fewer"),
            "half_link": Key(
                f"snake: half a link's length, joint to the wheel at the link's middle, {LENGTH}"
            ),
            "base_radius": Key(f"trident: the base's centre to an arm's joint, {LENGTH}"),
            "arm_length": Key(f"trident: an arm's joint to its wheel, {LENGTH}"),
            "alphas_deg": Key("trident: the three arms' corner angles on the base, degrees"),
            "wheelbase": Key(f"car: rear axle to front axle, {LENGTH}"),
        },
    ),
    "friction": Table(
        "The wheels on the floor, in physical units, the same for both worlds "
        "(docs/models.md). Optional: left out, each key takes the default shown.",
        {
            "lateral": Key(
                "wheel-floor Coulomb coefficient across a wheel (no unit, above 0; "
                "0.8 for rubber on a hard floor)",
                rm.DEFAULT_FRICTION.lateral,
            ),
            "rolling": Key(
                "rolling resistance coefficient C_rr: newtons along the wheel per newton "
                "of load (no unit, 0 or more)",
                rm.DEFAULT_FRICTION.rolling,
            ),
            "axle_nm": Key(
                "each wheel's friction torque on its axle, N m (0 or more)",
                rm.DEFAULT_FRICTION.axle_nm,
            ),
        },
        optional=True,
    ),
    "servo": Table(
        "The servos that drive the joints.",
        {
            "model": Key(f"{_MODELS}: its datasheet gives the no-load speed", "AX-12A"),
            "max_speed_rpm": Key(
                "the joints' top speed, rpm (above 0, at most the model's no-load speed; "
                "left out: that speed)",
                rm.SERVO_MAX_RPM.get("AX-12A"),
            ),
            "speed_limit": Key(
                "how Moving Speed acts on a joint in the physics world: "
                '"drive" caps the motor\'s drive at the duty that turns the unloaded motor at '
                "that speed (so a slow speed also caps the torque holding the joint), "
                '"profile" only limits how fast the target moves to the goal (docs/models.md)',
                rm.SPEED_LIMITS[0],
            ),
        },
    ),
    "limits": Table(
        "Limits every servo is held to (the robot's limits written to the servos).",
        {
            "torque": Key(
                f"the Torque Limit of every servo, in {_TORQUE_UNIT} "
                '("60%" or 60, above 0; left out: the servos keep theirs)',
                "60%",
            ),
        },
        optional=True,
    ),
    "joints": Table(
        "One table per actuated joint, in order phi1, phi2, ...",
        {
            "name": Key("the joint's name in reports and plots"),
            "servo_id": Key(
                f"Dynamixel ID of the servo that drives it (0-{MAX_SERVO_ID}, each joint its own)"
            ),
            "zero_tick": Key(
                "the servo's position at joint angle 0, in ticks "
                f"({rm.TICK_MIN}-{rm.TICK_MAX}, {(rm.TICK_MIN + rm.TICK_MAX + 1) // 2} is "
                "the servo's centre); "
                "`snakebot robot calibrate` measures it"
            ),
            "sign": Key(
                "1 if the servo's ticks grow as the link nearer the head turns "
                "counter-clockwise seen from above, -1 if the servo is mounted the other "
                "way round"
            ),
            "min_deg": Key("the joint's smallest angle, degrees from its zero"),
            "max_deg": Key("the joint's largest angle, degrees from its zero"),
        },
        array=True,
    ),
    "physics": Table(
        "The body the physics world builds, and the wheels' loads in both worlds. "
        "Optional: without it a robot has no size in metres.",
        {
            "unit_m": Key(
                "metres per length unit of [geometry] (1 for a robot measured in metres)", 1.0
            ),
            "link_mass_kg": Key(
                "one link's mass with its servo, brackets and axle, kg",
                rm.PHYSICS_DEFAULTS["link_mass_kg"],
            ),
            "wheel_radius_m": Key("a wheel's radius, m", rm.PHYSICS_DEFAULTS["wheel_radius_m"]),
            "wheel_mass_kg": Key("a wheel's mass, kg", rm.PHYSICS_DEFAULTS["wheel_mass_kg"]),
        },
        optional=True,
    ),
}
"""Every table and key of a robot file, in the order ``snakebot robot new`` writes them."""


def schema() -> dict[str, Any]:
    """The keys a robot file may have, as the loader checks them: None for a value, a set
    for a table's keys, a list holding that set for an array of tables."""
    shape: dict[str, Any] = dict.fromkeys(TABLES[""].keys)
    for name, table in TABLES.items():
        if name:
            shape[name] = [set(table.keys)] if table.array else set(table.keys)
    return shape
