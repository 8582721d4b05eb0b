"""Checks every gait must pass before it is written: joint limits and servo speed."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from snakebot.errors import InputError

if TYPE_CHECKING:
    from snakebot.model.robots import Robot


class GaitLimitError(InputError):
    """A gait leaves a joint's range or exceeds the servo's speed; nothing was written."""


def check_motion(
    robot: Robot,
    t: np.ndarray,
    phi: np.ndarray,
    dphi: np.ndarray | None,
    what: str = "the gait",
    check_range: bool = True,
    outcome: str = "no file was written",
) -> None:
    """Raise GaitLimitError at the first sample (by time) outside a limit.

    ``t``: sample times (s); ``phi``: joint angles (samples x joints, rad); ``dphi``:
    joint velocities (rad/s), or None to skip the speed check."""
    problems: list[tuple[float, str]] = []
    vmax = robot.max_speed_rad_s
    if not _any_outside(robot, phi, dphi, check_range):
        return  # the common case, in a few array operations (a search checks every run)
    for j, joint in enumerate(robot.joints):
        low = np.flatnonzero(phi[:, j] < joint.min_rad - 1e-12) if check_range else []
        high = np.flatnonzero(phi[:, j] > joint.max_rad + 1e-12) if check_range else []
        for idx, bound, word in (
            (low, joint.min_rad, "below its minimum"),
            (high, joint.max_rad, "above its maximum"),
        ):
            if len(idx):
                k = int(idx[0])
                problems.append(
                    (
                        float(t[k]),
                        (
                            f"joint {joint.name} (servo {joint.servo_id}) reaches "
                            f"{math.degrees(phi[k, j]):.1f} deg at t = {t[k]:.3f} s, {word} of "
                            f"{math.degrees(bound):.1f} deg"
                        ),
                    )
                )
        if dphi is not None:
            fast = np.flatnonzero(np.abs(dphi[:, j]) > vmax * (1 + 1e-9))
            if fast.size:
                k = int(fast[0])
                problems.append(
                    (
                        float(t[k]),
                        (
                            f"joint {joint.name} (servo {joint.servo_id}) moves at "
                            f"{abs(dphi[k, j]):.2f} rad/s at t = {t[k]:.3f} s, above the "
                            f"{robot.servo_model}'s maximum of {vmax:.2f} rad/s"
                        ),
                    )
                )
    if problems:
        problems.sort(key=lambda p: p[0])
        more = f" (and {len(problems) - 1} more violations)" if len(problems) > 1 else ""
        raise GaitLimitError(
            f"{what} is outside {robot.name}'s limits: {problems[0][1]}{more}. Reduce the "
            f"amplitude or offset (range) or the frequency (speed); {outcome}"
        )


def _any_outside(robot: Robot, phi: np.ndarray, dphi: np.ndarray | None, check_range: bool) -> bool:
    """Whether any sample breaks a limit check_motion checks (the same comparisons, all
    joints at once)."""
    if check_range:
        low = np.array([j.min_rad for j in robot.joints]) - 1e-12
        high = np.array([j.max_rad for j in robot.joints]) + 1e-12
        if (phi < low).any() or (phi > high).any():
            return True
    return dphi is not None and bool((np.abs(dphi) > robot.max_speed_rad_s * (1 + 1e-9)).any())


def check_ticks(
    robot: Robot,
    ticks: np.ndarray,
    period_s: float,
    loop: bool,
    angles: np.ndarray | None = None,
) -> None:
    """The table as the controller plays it: ticks within limits, and the speed of the
    linear interpolation between frames (including the wrap of a loop) within the servo's.
    ``angles``: the ticks already converted (robot.ticks_to_angles), if the caller has them."""
    t = np.arange(len(ticks)) * period_s
    phi = robot.ticks_to_angles(ticks) if angles is None else angles
    limits = np.array(robot.tick_limits).T
    if ((ticks < limits[0]) | (ticks > limits[1])).any():
        for j, (lo, hi) in enumerate(robot.tick_limits):
            bad = np.flatnonzero((ticks[:, j] < lo) | (ticks[:, j] > hi))
            if bad.size:
                k = int(bad[0])
                raise GaitLimitError(
                    f"frame {k} (t = {t[k]:.3f} s) sets joint {robot.joints[j].name} to tick "
                    f"{int(ticks[k, j])}, outside its limits {lo}..{hi}; no file was written"
                )
    following = np.concatenate((phi[1:], phi[:1])) if loop else phi[1:]
    speed = (following - phi[: len(following)]) / period_s
    check_motion(
        robot,
        t[: len(following)],
        phi[: len(following)],
        speed,
        what="the gait table (rounded to ticks, played frame to frame)",
        check_range=False,
    )


def check_serpenoid(
    robot: Robot,
    amplitude: float,
    omega: float,
    phases: Sequence[float],
    offset: float,
    duration: float,
    samples: int,
    *,
    what: str = "the gait",
    outcome: str = "no file was written",
) -> None:
    """The serpenoid A sin(omega t + phase_k) + offset sampled ``samples`` times over
    ``duration`` seconds, checked by :func:`check_motion` (angles and speeds). Both
    `gait serpenoid` and the controller's on-line serpenoid (`snakebot serpenoid`, over
    one whole cycle) are checked here."""
    reach = abs(amplitude)
    if reach * abs(omega) <= robot.max_speed_rad_s and all(
        joint.min_rad <= offset - reach and offset + reach <= joint.max_rad
        for joint in robot.joints
    ):
        return  # no sample can leave a limit the whole wave stays within
    t = np.linspace(0.0, duration, samples)
    args = omega * t[:, None] + np.asarray(phases, dtype=float)
    phi = amplitude * np.sin(args) + offset
    check_motion(robot, t, phi, amplitude * omega * np.cos(args), what=what, outcome=outcome)
