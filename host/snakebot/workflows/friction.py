"""The friction study: one gait in the physics world over a range of wheel-floor friction
coefficients, its distance per cycle beside the kinematic world's.

Both worlds take the same friction (the robot's ``[friction]``, its lateral coefficient
``mu`` varied here): the kinematic world without inertia (quasi-static Coulomb), the
physics world with it. The study shows how far apart they are at each ``mu``, how fast
the distance falls as the wheels start to slide, and (free wheels: no rolling resistance
or axle friction) what the rolling resistance costs.

Distances are the steady state's: a looping table is played ``STEADY_PASSES`` times and
the last pass is measured, since the physics world starts from rest and its first cycle
goes up to a quarter less far (docs/thesis.md, "The friction study"). Beside each
physics run the quasi-static model is also fed that run's own joint motion (the servos
as they moved under load, not as commanded): where the two worlds differ, that says
whether the joints' motion or the body's physics is the cause.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from typing import Any

import numpy as np

from snakebot.errors import InputError, quoted
from snakebot.formats.gaittable import GaitTable, layout
from snakebot.model.gait.common import table_motion
from snakebot.model.robots import Robot
from snakebot.workflows.predict import Prediction, predict_gait, predict_table, resolve_robot

DEFAULT_MU = (0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)
MAX_MU = 1000.0
"""The largest friction coefficient tried: rubber on concrete is about 1."""
MAX_MU_VALUES = 50
"""The most friction values one study runs (each is a MuJoCo run of the gait, played
STEADY_PASSES times over if it loops)."""
STEADY_PASSES = 3
"""How many times a looping table is played; the last pass is measured. The physics
world's start from rest is over by the second: snake5's serpenoids go the same distance
(to 0.1 %) in the third and the fifth pass (docs/thesis.md)."""


def parse_mu_values(mu: str) -> tuple[float, ...]:
    """The friction coefficients of the comma-separated ``mu``: each more than 0 and at
    most MAX_MU, MAX_MU_VALUES of them at most (InputError otherwise)."""
    try:
        values = tuple(float(v) for v in mu.split(",") if v.strip())
    except ValueError:
        values = ()
    if not values or not all(math.isfinite(v) and 0 < v <= MAX_MU for v in values):
        raise InputError(
            f"{quoted(mu)}: give friction coefficients more than 0 and at most {MAX_MU:g} "
            "separated by commas, e.g. 0.1,1,10"
        ).about("mu")
    if len(values) > MAX_MU_VALUES:
        raise InputError(
            f"{quoted(mu)}: {len(values):,} friction coefficients, at most {MAX_MU_VALUES} "
            "(each is a physics run of its own)"
        ).about("mu")
    return values


def _per_cycle(dx: float, dy: float, cycles: float) -> float:
    return math.hypot(dx, dy) / cycles


def _last(q: np.ndarray, passes: int, cycles: float) -> float:
    """Distance per cycle of the last of ``passes`` equal passes of the poses ``q``."""
    per = (len(q) - 1) // passes
    return _per_cycle(float(q[-1, 0] - q[-1 - per, 0]), float(q[-1, 1] - q[-1 - per, 1]), cycles)


def repeated(table: GaitTable, passes: int) -> GaitTable:
    """A looping ``table`` played ``passes`` times as one table (fewer if the controller's
    table could not hold them: at least once); a single-play table as it is."""
    fit = passes
    while fit > 1 and (
        fit * table.frame_count > layout.MAX_FRAME_COUNT
        or layout.table_size(table.joint_count, fit * table.frame_count) > layout.MAX_TABLE_BYTES
    ):
        fit -= 1
    if not table.loop or fit <= 1:
        return table
    metadata = dict(table.metadata)
    parameters = metadata.get("parameters")
    metadata["parameters"] = {
        **(parameters if isinstance(parameters, dict) else {}),
        "cycles": gait_cycles(table) * fit,
    }
    frames = np.tile(table.frames, (fit, 1))
    return replace(table, frames=frames, metadata=metadata)


def gait_cycles(table: GaitTable) -> float:
    """How many gait cycles one pass of the table holds (its metadata's, else 1)."""
    parameters = table.metadata.get("parameters")
    cycles = parameters.get("cycles") if isinstance(parameters, dict) else None
    return float(cycles) if isinstance(cycles, int | float) and cycles > 0 else 1.0


def friction_study(
    table: GaitTable,
    robot: str | Robot | None,
    mu_values: Sequence[float] = DEFAULT_MU,
    name: str = "<table>",
    progress: Callable[[float, Prediction], None] | None = None,
    passes: int = STEADY_PASSES,
) -> dict[str, Any]:
    """Play ``table`` (a looping one ``passes`` times, :func:`repeated`) in the kinematic
    world once and in the physics world at each friction coefficient; JSON-able results:
    distances per cycle of the last pass (the robot's length units), each physics run's
    first cycle beside it, and ``dx``, ``dy``, ``dtheta`` over the whole play."""
    chosen = resolve_robot(table, robot)
    cycles = gait_cycles(table)
    played = repeated(table, passes)
    n = round(gait_cycles(played) / cycles)
    kinematic = predict_gait(played, chosen)
    samples = len(kinematic.emulated.t)
    period = kinematic.world_period_s
    free_wheels = replace(chosen.friction, rolling=0.0, axle_nm=0.0)
    free, _ = predict_table(replace(chosen, friction=free_wheels), played, samples)
    points = []
    for mu in mu_values:
        result = predict_gait(played, chosen, world="mujoco", mu=mu)
        d = result.emulated.displacement()
        at_mu = replace(chosen, friction=replace(chosen.friction, lateral=mu))
        k = predict_table(at_mu, played, samples)[0].q
        # the quasi-static model on the joints as the physics world's servos moved them
        on_joints = table_motion(at_mu, result.emulated.phi, period, False).trajectory.q
        last = (samples - 1) // n * (n - 1)  # the last pass's first sample
        speed, t = np.abs(result.emulated.slip[last:]), result.emulated.t[last:]
        slip = (speed[1:] + speed[:-1]) * 0.5 * np.diff(t)[:, None]
        points.append(
            {
                "mu": mu,
                "kinematic_distance_per_cycle": _last(k, n, cycles),
                "kinematic_on_physics_joints_per_cycle": _last(on_joints, n, cycles),
                "dx": d["dx"],
                "dy": d["dy"],
                "dtheta": d["dtheta"],
                "distance_per_cycle": _last(result.emulated.pose, n, cycles),
                "first_pass_distance_per_cycle": _per_cycle(
                    *(result.emulated.pose[(samples - 1) // n, :2] - result.emulated.pose[0, :2]),
                    cycles,
                ),
                "slip_distance_per_cycle": float(np.sum(slip)) / cycles,
            }
        )
        if progress is not None:
            progress(mu, result)
    em = kinematic.emulated.displacement()
    return {
        "gait": name,
        "robot": chosen.name,
        "cycles": cycles,
        "passes": n,
        "units": "m" if chosen.physics and chosen.physics.unit_m == 1.0 else "robot units",
        "friction": asdict(chosen.friction),
        "kinematic": {**em, "distance_per_cycle": _last(kinematic.emulated.pose, n, cycles)},
        "kinematic_free_wheels": {
            "dx": float(free.q[-1, 0] - free.q[0, 0]),
            "dy": float(free.q[-1, 1] - free.q[0, 1]),
            "distance_per_cycle": _last(free.q, n, cycles),
        },
        "points": points,
    }
