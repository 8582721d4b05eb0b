"""The physics world's time step (issue #31): at the default step the figures a user reads
have converged. Halving the step changes the distance travelled, the wheels' slide, the
joints' mechanical work and the motors' electrical energy by less than 2 % each, and no
joint's work by more than 2 % of the total. At twice the default step the small, fast
gait below misses that (so the default is not finer than it needs to be, and this test
can fail).

The gaits: snake5's serpenoid the physics tests play (30 deg, 1 Hz, delta 90 deg) and the
slowest to converge of a sweep (docs/models.md, "The physics world's time step"): small
and fast, 20 deg at 2 Hz with delta 120 deg."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from snakebot.model.gait import serpenoid
from snakebot.model.robots import load_robot
from snakebot.workflows.predict import predict_gait

pytest.importorskip("mujoco")

from snakebot.sim.physics import world as physics_world  # noqa: E402 (needs MuJoCo)
from snakebot.sim.physics.mjcf import TIMESTEP_S  # noqa: E402

SNAKE5 = load_robot("snake5")
GAITS = {  # amplitude, omega, delta (deg), cycles
    "serpenoid": (30.0, 180.0, 90.0, 1),
    "small-and-fast": (20.0, 360.0, 120.0, 2),
}
TOLERANCE = 0.02
FIGURES = ("distance", "slide", "work", "electrical")


def figures(gait: str, step: float, monkeypatch: pytest.MonkeyPatch) -> dict[str, object]:
    """What a prediction on the physics world reports, run at time step ``step``."""
    amplitude, omega, delta, cycles = GAITS[gait]
    table = serpenoid(
        SNAKE5, math.radians(amplitude), math.radians(omega), math.radians(delta), cycles=cycles
    ).gait_table()
    chosen = functools.partial(physics_world.PhysicsWorld, timestep=step)
    with monkeypatch.context() as m:
        m.setattr(physics_world, "PhysicsWorld", chosen)
        rec = predict_gait(table, "snake5", world="mujoco").emulated
    d = rec.displacement()
    return {
        "distance": math.hypot(d["dx"], d["dy"]),
        "slide": float(rec.slip_distance().sum()),
        "work": float(rec.energy.sum()),
        "electrical": float(rec.electrical.sum()),
        "joints": np.asarray(rec.energy),
    }


def changes(coarse: dict[str, object], fine: dict[str, object]) -> dict[str, float]:
    """Relative change of each figure from ``fine`` to ``coarse``; per joint, the largest
    change of a joint's work over the total work."""
    out = {k: abs(coarse[k] / fine[k] - 1) for k in FIGURES}  # type: ignore[operator]
    joints = np.abs(coarse["joints"] - fine["joints"]).max()  # type: ignore[operator]
    out["joint work"] = float(joints / abs(fine["work"]))  # type: ignore[arg-type]
    return out


@pytest.mark.parametrize("gait", GAITS)
def test_halving_the_default_step_changes_no_figure_by_2_percent(gait, monkeypatch):
    found = changes(
        figures(gait, TIMESTEP_S, monkeypatch), figures(gait, TIMESTEP_S / 2, monkeypatch)
    )
    assert max(found.values()) < TOLERANCE, found


def test_at_twice_the_default_step_the_small_fast_gait_has_not_converged(monkeypatch):
    found = changes(
        figures("small-and-fast", 2 * TIMESTEP_S, monkeypatch),
        figures("small-and-fast", TIMESTEP_S, monkeypatch),
    )
    assert max(found.values()) > TOLERANCE, found
