"""The friction study: one gait in the physics world over a range of wheel-floor friction
coefficients, its distance per cycle beside the kinematic world's.

Both worlds take the same friction (the robot's ``[friction]``, its lateral coefficient
``mu`` varied here): the kinematic world without inertia (quasi-static Coulomb), the
physics world with it. The study shows how far apart they are at each ``mu``, how fast
the distance falls as the wheels start to slide, and (free wheels: no rolling resistance
or axle friction) what the rolling resistance costs.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from typing import Any

import numpy as np

from snakebot.errors import InputError, quoted
from snakebot.formats.gaittable import GaitTable
from snakebot.model.robots import Robot
from snakebot.workflows.predict import Prediction, predict_gait, predict_table, resolve_robot

DEFAULT_MU = (0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0)
MAX_MU = 1000.0
"""The largest friction coefficient tried: rubber on concrete is about 1."""
MAX_MU_VALUES = 50
"""The most friction values one study runs (each is a MuJoCo run of the whole gait)."""


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
) -> dict[str, Any]:
    """Play ``table`` in the kinematic world once and in the physics world at each
    friction coefficient; JSON-able results (distances in the robot's length units)."""
    chosen = resolve_robot(table, robot)
    cycles = gait_cycles(table)
    kinematic = predict_gait(table, chosen)
    samples = len(kinematic.emulated.t)
    free_wheels = replace(chosen.friction, rolling=0.0, axle_nm=0.0)
    free, _ = predict_table(replace(chosen, friction=free_wheels), table, samples)
    em = kinematic.emulated.displacement()
    points = []
    for mu in mu_values:
        result = predict_gait(table, chosen, world="mujoco", mu=mu)
        d = result.emulated.displacement()
        at_mu = replace(chosen, friction=replace(chosen.friction, lateral=mu))
        k = predict_table(at_mu, table, samples)[0].q
        points.append(
            {
                "mu": mu,
                "kinematic_distance_per_cycle": _per_cycle(
                    float(k[-1, 0] - k[0, 0]), float(k[-1, 1] - k[0, 1]), cycles
                ),
                "dx": d["dx"],
                "dy": d["dy"],
                "dtheta": d["dtheta"],
                "distance_per_cycle": _per_cycle(d["dx"], d["dy"], cycles),
                "slip_distance_per_cycle": float(np.sum(result.emulated.slip_distance())) / cycles,
            }
        )
        if progress is not None:
            progress(mu, result)
    free_d = free.q[-1, :2] - free.q[0, :2]
    return {
        "gait": name,
        "robot": chosen.name,
        "cycles": cycles,
        "units": "m" if chosen.physics and chosen.physics.unit_m == 1.0 else "robot units",
        "friction": asdict(chosen.friction),
        "kinematic": {**em, "distance_per_cycle": _per_cycle(em["dx"], em["dy"], cycles)},
        "kinematic_free_wheels": {
            "dx": float(free_d[0]),
            "dy": float(free_d[1]),
            "distance_per_cycle": _per_cycle(float(free_d[0]), float(free_d[1]), cycles),
        },
        "points": points,
    }
