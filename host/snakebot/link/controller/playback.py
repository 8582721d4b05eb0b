"""Starting and stopping the controller's gaits: the stored table, or the serpenoid that
the firmware computes on line.

    status = play(ctl, speed=1.5, steer=math.radians(10))
    status = serpenoid(ctl, SerpenoidSettings(amplitude=0.5, omega=3.14, delta=2.09))
    status = stop(ctl, clear=True)

Values are given in the user's units (a speed factor, radians, rad/s) and converted to
the registers' (1/256, position ticks, milliradians); a value the control table would
refuse is refused here first, with the range in the user's units. After the command
the controller's State is read back: a gait that did not start is an error naming why.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from snakebot.link.controller import messages as words
from snakebot.link.controller.client import ControllerClient, RosterEntry
from snakebot.link.controller.errors import ControllerInputError, ControllerStateError
from snakebot.link.controller.limits import VERIFY_TIMEOUT_S, LimitsFailed, not_held, wait_settled
from snakebot.model.gait.limits import check_serpenoid as check_serpenoid_motion
from snakebot.model.robots import Robot

SPEED = "x"
"""The unit of Speed Scale: a factor on the generated speed (1 = as generated)."""

CYCLE_SAMPLES = 4097
"""Samples of one serpenoid cycle the host checks: a peak falls at most 1/8192 of a turn
from one, so it is missed by under 2e-7 of the amplitude, far below a position tick."""

REFUSALS = {
    "SAFE_STATE": "the controller is in the safe state: `snakebot stop --clear` leaves it",
    "NO_TABLE": "it has no gait table: upload one with `snakebot upload`",
    "EMPTY_ROSTER": "its roster is empty: set it from the robot's description",
    "BAD_JOINT_LIMITS": "a roster joint's Min Tick is above its Max Tick or outside the "
    "robot's limits: set the roster again from the robot's description",
    "LIMITS_NOT_VERIFIED": "the servos do not hold the robot's limits yet: see "
    "`snakebot limits show`",
    "TABLE_OUTSIDE_LIMITS": "the active table leaves the robot's limits: upload a table "
    "made for them",
    "AMPLITUDE": "A + |offset| (with the steering) takes a joint outside its roster limits "
    "(Min Tick..Max Tick): lower the amplitude or the offset",
    "SPEED": "A * |omega| * speed is above the servo's no-load speed: lower omega, the "
    "amplitude or the speed",
}
"""What each Refusal Reason (Program page) means, and the fix."""

REFUSAL_PARAMS: dict[str, tuple[str, ...]] = {
    "EMPTY_ROSTER": ("robot",),
    "BAD_JOINT_LIMITS": ("robot",),
    "AMPLITUDE": ("amplitude", "offset", "steer"),
    "SPEED": ("omega", "amplitude", "speed"),
}
"""The parameters (the CLI's options) each refusal's fix is about."""

RUNTIME_REFUSALS = frozenset({"SAFE_STATE", "LIMITS_NOT_VERIFIED"})
"""Refusal Reasons that are the controller's state, not the request (exit 1): the same
reasons that ``play`` and ``serpenoid`` check for first."""

FINISH_GRACE_S = 0.05
"""A table played once may already be over when the State is read back: it counts as
played if its duration (at the chosen speed) is shorter than the time since the command
plus this."""


@dataclass(frozen=True)
class SerpenoidSettings:
    """The on-line serpenoid: joint k follows A sin(omega t + k delta) + phi0 (radians)."""

    amplitude: float
    omega: float
    delta: float
    offset: float = 0.0


def refusal_reason(ctl: ControllerClient) -> tuple[str, str]:
    """The controller's last Refusal Reason (Program page): its name and what it means,
    with the fix."""
    code = ctl.read("Refusal Reason")["Refusal Reason"]
    names = {v: k for k, v in ctl.table.enums["Refusal Reason"].items()}
    name = names.get(code, str(code))
    return name, REFUSALS.get(name, "see protocol/controller.md")


def _fmt_angle(rad: float, rate: bool = False) -> str:
    unit = "rad/s" if rate else "rad"
    dunit = "deg/s" if rate else "deg"
    return f"{rad:.4g} {unit} ({math.degrees(rad):.4g} {dunit})"


def _raw(
    ctl: ControllerClient,
    register: str,
    value: float,
    param: str,
    rate: bool = False,
    angle: bool = True,
) -> int:
    """``value`` (radians, rad/s, or a speed factor) of parameter ``param`` as the
    register's integer, or ControllerInputError with the range in those units."""
    reg = ctl.table.register(register)
    assert reg.scale is not None, register  # every register set here has a unit
    scale = reg.scale.per_unit(("rad/s" if rate else "rad") if angle else SPEED)
    raw = int(round(value * scale))
    if reg.accepts(raw):
        return raw
    low, high = reg.value_range()
    if angle:
        shown = f"{param} {_fmt_angle(value, rate)}"
        span = f"{_fmt_angle(low / scale, rate)} .. {_fmt_angle(high / scale, rate)}"
    else:
        shown, span = f"{param} {value:g}", f"{low / scale:.4g} .. {high / scale:.4g}"
    unit = f", in {reg.unit}" if reg.unit else ""
    raise ControllerInputError(
        f"{shown} is outside what the controller takes: {span} "
        f"(its {reg.name} register takes {low}..{high}{unit}); nothing was changed"
    ).about(param)


def speed_scale(ctl: ControllerClient, speed: float) -> int:
    """Speed Scale for a speed factor (1 = as generated)."""
    return _raw(ctl, "Speed Scale", speed, "speed", angle=False)


def steering_offset(ctl: ControllerClient, steer: float) -> int:
    """Steering Offset in ticks for an angle in radians added to every joint."""
    return _raw(ctl, "Steering Offset", steer, "steer")


def _status(ctl: ControllerClient, regs: dict[str, int]) -> dict[str, Any]:
    """The controller's state after a command, for printing and --json."""

    def units(name: str, unit: str) -> float:
        return ctl.table.register(name).to_units(regs[name], unit)

    return {
        "state": words.state_name(regs["State"], ctl.table),
        "error_flags": words.flag_names(regs["Error Flags"], ctl.table),
        "speed": units("Speed Scale", SPEED),
        "steer_rad": units("Steering Offset", "rad"),
        "steering_offset_ticks": regs["Steering Offset"],
        "loop": bool(regs["Loop"]),
        "joint_count": regs["Joint Count"],
        "table": {
            "bytes": regs["Table Size"],
            "crc": f"0x{regs['Table CRC']:08x}",
            "joints": regs["Table Joints"],
            "frames": regs["Table Frames"],
            "period_ms": regs["Table Period"],
        },
        "serpenoid": {
            "amplitude_rad": units("Serp Amplitude", "rad"),
            "omega_rad_s": units("Serp Omega", "rad/s"),
            "delta_rad": units("Serp Delta", "rad"),
            "offset_rad": units("Serp Phi0", "rad"),
        },
    }


def _ready(ctl: ControllerClient, regs: dict[str, int]) -> None:
    """ControllerStateError if the controller is in the safe state."""
    if words.state_name(regs["State"], ctl.table) == "SAFE":
        flags = regs["Error Flags"]
        raise ControllerStateError(
            "the controller is in the safe state and starts nothing: "
            f"{words.describe_flags(flags, ctl.table)}. {words.safe_fix(flags, ctl.table)}"
            "; then leave the safe state with `snakebot stop --clear`"
        )


def _start(
    ctl: ControllerClient,
    before: dict[str, int],
    command: str,
    want: str,
    finished_ok: float | None = None,
) -> dict[str, Any]:
    # after a roster change the controller checks the servos' angle limits first
    state, _ = wait_settled(ctl)
    if state not in ("NONE", "VERIFIED"):
        raise LimitsFailed(not_held(ctl, state, VERIFY_TIMEOUT_S))
    sent = time.monotonic()
    ctl.command(command)
    after = ctl.read_all()
    state = words.state_name(after["State"], ctl.table)
    if state == want:
        return _status(ctl, after)
    refused_bit = ctl.table.enums["Error Flags"]["REFUSED"]
    newly_refused = after["Error Flags"] & refused_bit and not before["Error Flags"] & refused_bit
    if (
        state == "IDLE"
        and not newly_refused
        and finished_ok is not None
        and finished_ok <= time.monotonic() - sent + FINISH_GRACE_S
    ):
        return _status(ctl, after)  # a short table played once is already over
    if newly_refused:
        name, why = refusal_reason(ctl)
        refused = ControllerStateError if name in RUNTIME_REFUSALS else ControllerInputError
        raise refused(
            f"the controller refused {command} (Refusal Reason {name}): {why}; nothing was started"
        ).about(*REFUSAL_PARAMS.get(name, ()))
    raise ControllerStateError(
        f"the controller did not start ({command} left it {state}; error flags: "
        f"{words.describe_flags(after['Error Flags'], ctl.table)}): check its state with "
        "`snakebot monitor`"
    )


def play(
    ctl: ControllerClient, *, loop: bool | None = None, speed: float = 1.0, steer: float = 0.0
) -> dict[str, Any]:
    """Play the active table from its first frame. ``loop``: None keeps the table's own
    setting. ``speed``: factor on the table's time; ``steer``: radians added to every
    joint (negated for reversed joints). An active program (protocol/program.md) is run
    with PROGRAM_RUN instead: speed runs its time and steering steers its serpenoid
    segments (protocol/program.md, "Live steering"); loop does not apply."""
    values = {
        "Speed Scale": speed_scale(ctl, speed),
        "Steering Offset": steering_offset(ctl, steer),
    }
    ctl.identify()
    before = ctl.read_all()
    _ready(ctl, before)
    if before["Table Size"] == 0:
        raise ControllerInputError(
            "the controller has no gait table to play: generate one with `snakebot gait ...` "
            "and upload it with `snakebot upload GAIT`"
        )
    if is_program(before):
        ctl.write(values)
        # a short program may be over before the state is read back: IDLE is fine then
        return {**_start(ctl, before, "PROGRAM_RUN", "PLAYING", finished_ok=0.0), "program": True}
    values["Loop"] = (before["Table Flags"] & 1) if loop is None else int(loop)
    ctl.write(values)
    once_s = None
    if not values["Loop"]:
        period_s = ctl.table.register("Table Period").to_units(before["Table Period"], "s")
        speed = ctl.table.register("Speed Scale").to_units(values["Speed Scale"], SPEED)
        once_s = (before["Table Frames"] - 1) * period_s / speed
    return _start(ctl, before, "PLAY", "PLAYING", finished_ok=once_s)


def is_program(regs: dict[str, int]) -> bool:
    """Whether the active table registers describe a program: a table always has frames,
    a program shows Table Frames 0 (protocol/controller.md, "Uploading a program")."""
    return regs["Table Size"] > 0 and regs["Table Frames"] == 0


def roster_from_robot(robot: Robot) -> list[RosterEntry]:
    """The controller's roster for ``robot``: IDs, directions, zero ticks and limits."""
    return [
        RosterEntry(
            id=j.servo_id,
            reverse=j.sign < 0,
            zero_tick=j.zero_tick,
            min_tick=j.tick_range[0],
            max_tick=j.tick_range[1],
        )
        for j in robot.joints
    ]


def check_serpenoid(
    robot: Robot, settings: SerpenoidSettings, *, speed: float = 1.0, steer: float = 0.0
) -> None:
    """GaitLimitError unless the on-line serpenoid keeps ``robot``'s joints within their
    limits and the servo's speed over a whole cycle, as the controller checks before it
    starts (the same check as `gait serpenoid`'s)."""
    rate = settings.omega * speed
    cycle = 2 * math.pi / abs(rate) if rate else 0.0
    phases = [k * settings.delta for k in range(robot.n_joints)]
    offset = settings.offset + steer
    check_serpenoid_motion(
        robot,
        settings.amplitude,
        rate,
        phases,
        offset,
        cycle,
        CYCLE_SAMPLES,
        what="the serpenoid",
        outcome="nothing was sent",
    )


def serpenoid(
    ctl: ControllerClient,
    settings: SerpenoidSettings,
    *,
    speed: float = 1.0,
    steer: float = 0.0,
    roster: Iterable[RosterEntry] | None = None,
    robot: Robot | None = None,
) -> dict[str, Any]:
    """Start the firmware's serpenoid on the roster (``roster`` replaces it first).
    ``robot``: check its limits first (GaitLimitError, nothing sent); without it the
    controller's own check is explained if it refuses."""
    if robot is not None:
        check_serpenoid(robot, settings, speed=speed, steer=steer)
    values = {
        "Serp Amplitude": _raw(ctl, "Serp Amplitude", settings.amplitude, "amplitude"),
        "Serp Omega": _raw(ctl, "Serp Omega", settings.omega, "omega", rate=True),
        "Serp Delta": _raw(ctl, "Serp Delta", settings.delta, "delta"),
        "Serp Phi0": _raw(ctl, "Serp Phi0", settings.offset, "offset"),
        "Speed Scale": speed_scale(ctl, speed),
        "Steering Offset": steering_offset(ctl, steer),
    }
    ctl.identify()
    before = ctl.read_all()
    _ready(ctl, before)
    if roster is not None:
        ctl.set_roster(roster)
        before = ctl.read_all()
    if before["Joint Count"] == 0:
        raise ControllerInputError(
            "the controller's roster is empty, so the serpenoid has no joints to drive: "
            "name the robot (snake3, snake5, trident or a robot file) to set it, or upload "
            "a gait table for the robot first"
        ).about("robot")
    bad = [j for j in ctl.roster(before["Joint Count"]) if j.min_tick > j.max_tick]
    if bad:
        raise ControllerInputError(
            f"roster joint {bad[0].joint} (servo {bad[0].id}) has Min Tick {bad[0].min_tick} "
            f"above Max Tick {bad[0].max_tick}: name the robot to set the roster again"
        ).about("robot")
    ctl.write(values)
    return _start(ctl, before, "SERPENOID", "SERPENOID")


def stop(ctl: ControllerClient, *, clear: bool = False) -> dict[str, Any]:
    """Stop the gait (servos hold their last goal); ``clear`` also clears Error Flags and
    leaves the safe state."""
    ctl.identify()
    ctl.command("STOP")
    if clear:
        ctl.command("CLEAR")
    return _status(ctl, ctl.read_all())
