"""Robot descriptions as plain data: geometry, friction, and one ``Joint`` per servo."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np

from snakebot.errors import InputError
from snakebot.facts import devices

_POSITION = devices.ax12().require_position()
#: AX-12 position units, from its device description (the AX-12 family shares them).
TICKS_PER_RAD = _POSITION.ticks_per_rad
TICK_MIN, TICK_MAX = _POSITION.range
#: The servo's Torque Limit register, whose range and unit a robot's torque limit takes
#: (the firmware's range check is generated from the same description).
TORQUE_LIMIT = devices.ax12().register("Torque Limit")

#: No-load maximum joint speed per servo model (ROBOTIS e-Manual: AX-12A 59 rpm at 12 V,
#: AX-12W 54 rpm in joint mode), from the device descriptions, which the firmware shares.
SERVO_MAX_RPM = {
    name: rpm
    for name in devices.names("servo")
    if (rpm := devices.load(name).max_speed_rpm) is not None
}


#: How Moving Speed acts on a joint in the physics world (docs/models.md, "The servo's
#: speed limit"): "drive", it caps the motor's drive at the duty that turns the unloaded
#: motor at that speed, so a slow speed also caps the torque that holds the joint; or
#: "profile", it only limits how fast the servo's target moves to the goal, and the full
#: drive (within Torque Limit) holds the joint. The first is the default.
SPEED_LIMITS = ("drive", "profile")


#: Standard gravity (m/s^2): the wheels' loads are the masses' weights.
GRAVITY_M_S2 = 9.80665

PHYSICS_DEFAULTS: dict[str, float] = {
    "link_mass_kg": 0.08,  # an AX-12A (55 g) with its brackets and wheel axle
    "wheel_radius_m": 0.02,
    "wheel_mass_kg": 0.01,
}
"""``[physics]`` values a robot may leave out (``unit_m`` has no default); the masses
also give a robot without a ``[physics]`` table its wheels' loads."""


class RobotError(InputError):
    """A robot description that cannot be used (file missing, malformed, inconsistent)."""


def joint_name(index: int) -> str:
    """The name of joint ``index`` (0 = the first) when a description gives none: phi1, ..."""
    return f"phi{index + 1}"


@dataclass(frozen=True)
class Joint:
    """One actuated joint: the servo driving it and how its ticks map to the angle."""

    name: str
    servo_id: int
    zero_tick: int  # tick value at phi = 0
    sign: int  # +1: ticks grow with phi; -1: the servo is mounted the other way round
    min_rad: float
    max_rad: float

    def angle_to_tick(self, phi: float) -> int:
        return int(round(self.zero_tick + self.sign * phi * TICKS_PER_RAD))

    def tick_to_angle(self, tick: float) -> float:
        return (tick - self.zero_tick) / (self.sign * TICKS_PER_RAD)

    @property
    def tick_range(self) -> tuple[int, int]:
        """(min_tick, max_tick) covering the joint's allowed angles."""
        a, b = self.angle_to_tick(self.min_rad), self.angle_to_tick(self.max_rad)
        return (min(a, b), max(a, b))


@dataclass(frozen=True)
class Physics:
    """The robot's size and masses (the robot TOML's ``[physics]`` table): both worlds
    take the wheels' loads from them, the physics world its bodies. ``unit_m``: metres
    per length unit of ``[geometry]`` (1 for a robot measured in metres; a dimensionless
    thesis robot gets the size a lab would build). Masses in kg, the wheel radius in
    metres."""

    unit_m: float
    link_mass_kg: float
    wheel_radius_m: float
    wheel_mass_kg: float


@dataclass(frozen=True)
class Friction:
    """The wheels on the floor, in physical units (the robot TOML's ``[friction]``),
    the same for both worlds (docs/models.md says where the defaults come from).
    ``lateral``: the wheel-floor Coulomb coefficient across a wheel (sideways sliding);
    ``rolling``: the rolling resistance coefficient C_rr (force along the wheel per
    newton of load); ``axle_nm``: each wheel's Coulomb friction torque on its axle."""

    lateral: float
    rolling: float
    axle_nm: float


#: The defaults of ``[friction]``; docs/models.md ("Friction in physical units") gives
#: their sources: rubber on a hard lab floor (0.8), a small solid rubber wheel's rolling
#: resistance (0.01), a plastic hub turning on a 3 mm shaft under 0.9 N (3e-4 N m).
DEFAULT_FRICTION = Friction(lateral=0.8, rolling=0.01, axle_nm=3e-4)


@dataclass(frozen=True)
class Robot:
    """A wheeled snake (``kind == "snake"``), trident (``kind == "trident"``) or car
    (``kind == "car"``).

    Snake: ``links`` links of length ``2 * l``, a wheel at each link's middle; link 1's
    free end (the reference point) is the tail, link N's the head.
    Trident: base radius ``r``, arm length ``l``, arm corners at ``alphas`` (radians).
    Car (the thesis's first chapter): wheelbase ``l``; its one joint is the steering
    angle Phi, and the drive is an input, not a joint. It has a field model only
    (``snakebot model fields``), no wheel-by-wheel model in the C core.
    """

    name: str
    kind: Literal["snake", "trident", "car"]
    joints: tuple[Joint, ...]
    servo_model: str
    max_speed_rad_s: float
    l: float  # noqa: E741 - the thesis's symbol: half-link (snake) or arm length (trident)
    r: float = 0.0
    alphas: tuple[float, ...] = ()
    links: int = 0
    friction: Friction = DEFAULT_FRICTION
    description: str = ""
    physics: Physics | None = None  # None: the TOML has no [physics] table
    torque_limit: int | None = None  # raw Torque Limit for every servo; None: leave theirs
    speed_limit: str = SPEED_LIMITS[0]  # how Moving Speed acts in the physics world
    source: str = field(default="", compare=False)  # file it came from

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @property
    def n_wheels(self) -> int:
        return {"snake": self.links, "trident": 3, "car": 4}[self.kind]

    def wheel_masses_kg(self) -> np.ndarray:
        """The mass each wheel carries (kg), from ``[physics]`` (or the defaults). A
        snake's link and wheel rest on the link's wheel (the link's middle); a trident's
        base and arms share its three wheels equally (exact at its symmetric home pose,
        and how the loads are taken everywhere)."""
        phys = self.physics
        link = PHYSICS_DEFAULTS["link_mass_kg"] if phys is None else phys.link_mass_kg
        wheel = PHYSICS_DEFAULTS["wheel_mass_kg"] if phys is None else phys.wheel_mass_kg
        each = (link + 3 * (link + wheel)) / 3 if self.kind == "trident" else link + wheel
        return np.full(self.n_wheels, each)

    def wheel_loads_n(self) -> np.ndarray:
        """Each wheel's normal load (N): the weight of ``wheel_masses_kg``."""
        return self.wheel_masses_kg() * GRAVITY_M_S2

    def wheel_friction_n(self, friction: Friction | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Per wheel, in newtons: the Coulomb force across it when it slides (mu N) and
        the force resisting its rolling (C_rr N plus the axle's torque over the wheel's
        radius): the weights of the quasi-static friction model (docs/models.md)."""
        f = self.friction if friction is None else friction
        radius = (
            PHYSICS_DEFAULTS["wheel_radius_m"]
            if self.physics is None
            else self.physics.wheel_radius_m
        )
        loads = self.wheel_loads_n()
        return f.lateral * loads, f.rolling * loads + f.axle_nm / radius

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the state coordinates q = (x, y, theta, phi_1, ...)."""
        return ("x", "y", "theta") + tuple(j.name for j in self.joints)

    @property
    def servo_ids(self) -> tuple[int, ...]:
        return tuple(j.servo_id for j in self.joints)

    @cached_property
    def tick_limits(self) -> tuple[tuple[int, int], ...]:
        return tuple(j.tick_range for j in self.joints)

    @property
    def length_unit(self) -> str:
        """The unit of the robot's lengths (its ``[geometry]``, and every distance and pose
        computed from it) as printed: ``m`` for a robot measured in metres, else ``u``,
        the robot's own unit (the thesis robots are dimensionless)."""
        return "m" if self.physics is not None and self.physics.unit_m == 1.0 else "u"

    @property
    def length_legend(self) -> str:
        """What ``u`` is, for a report to print once (empty for a robot in metres)."""
        if self.length_unit == "m":
            return ""
        twin = f"; 1 u = {self.physics.unit_m:g} m on its physical twin" if self.physics else ""
        return f"lengths in u, {self.name}'s own unit (its [geometry]{twin})"

    @property
    def torque_limit_percent(self) -> float | None:
        """The robot-wide torque limit in the servo's unit (% of stall torque), if set."""
        if self.torque_limit is None:
            return None
        return TORQUE_LIMIT.to_units(self.torque_limit)

    @cached_property
    def _tick_map(self) -> tuple[np.ndarray, np.ndarray]:
        """Each joint's zero tick and sign (read-only arrays, built once per robot: a
        search converts a table per run)."""
        zero = np.array([j.zero_tick for j in self.joints], dtype=float)
        sign = np.array([j.sign for j in self.joints], dtype=float)
        zero.flags.writeable = sign.flags.writeable = False
        return zero, sign

    def angles_to_ticks(self, phi: np.ndarray) -> np.ndarray:
        """Joint angles (radians, last axis = joints) to AX-12 goal ticks (int64, rounded)."""
        phi = np.asarray(phi, dtype=float)
        if phi.shape[-1:] != (self.n_joints,):
            raise RobotError(
                f"{self.name} has {self.n_joints} joints but got angles of shape {phi.shape}: "
                "give one angle per joint in the last axis"
            )
        zero, sign = self._tick_map
        return np.rint(zero + sign * phi * TICKS_PER_RAD).astype(np.int64)

    def ticks_to_angles(self, ticks: np.ndarray) -> np.ndarray:
        """AX-12 ticks (last axis = joints) to joint angles in radians."""
        ticks = np.asarray(ticks, dtype=float)
        if ticks.shape[-1:] != (self.n_joints,):
            raise RobotError(
                f"{self.name} has {self.n_joints} joints but got ticks of shape {ticks.shape}: "
                "give one tick value per joint in the last axis"
            )
        zero, sign = self._tick_map
        return (ticks - zero) / (sign * TICKS_PER_RAD)
