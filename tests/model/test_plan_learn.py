"""The closed loop's learned response: from loops played on a floor that scales and
turns every motion the same way, it learns that map and asks the model for what makes
the floor move the body as wanted."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snakebot.model.plan.learn import MOST_CORRECTION, Response

SCALE = 2.0  # body length


def floor(scale: float, turn: float, heading_gain: float) -> np.ndarray:
    """A slipping floor as a map from planned to observed motion (x, y, theta)."""
    c, s = math.cos(turn), math.sin(turn)
    return np.array(
        [[scale * c, -scale * s, 0.0], [scale * s, scale * c, 0.0], [0, 0, heading_gain]]
    )


@pytest.mark.parametrize("seed", range(5))
def test_learns_a_consistent_floor_and_undoes_it(seed):
    rng = np.random.default_rng(seed)
    true = floor(rng.uniform(0.5, 1.5), rng.uniform(-0.6, 0.6), rng.uniform(0.5, 1.5))
    response = Response(SCALE)
    for _ in range(12):
        planned = np.r_[rng.normal(0, 0.2 * SCALE, 2), rng.normal(0, 0.2)]
        response.add(planned, true @ planned)
    # the prior and the forgetting hold it a few hundredths from the truth
    assert response.gain == pytest.approx(true, abs=0.08)
    wanted = np.array([0.1 * SCALE, -0.05 * SCALE, 0.05])
    moved = true @ response.command(wanted)
    model_only = true @ wanted
    w = response.weights
    # the corrected loop lands far nearer than the model's loop would
    assert np.linalg.norm((moved - wanted) * w) < 0.3 * np.linalg.norm((model_only - wanted) * w)


def test_starts_as_the_model_and_moves_part_way_on_one_loop():
    response = Response(SCALE)
    wanted = np.array([0.1, 0.2, 0.03])
    assert response.command(wanted) == pytest.approx(wanted)
    planned = np.array([0.2 * SCALE, 0.0, 0.0])
    response.add(planned, 0.5 * planned)  # the floor moved the body half as far
    g = response.gain[0, 0]
    assert 0.5 < g < 0.75  # towards the observed half, held back by the prior


def test_a_near_singular_gain_never_asks_for_far_more_than_wanted():
    response = Response(SCALE)
    for _ in range(5):  # the floor did nothing with any turn
        response.add(np.array([0.0, 0.0, 0.2]), np.array([0.0, 0.0, 1e-6]))
    wanted = np.array([0.0, 0.0, 0.1])
    asked = response.command(wanted)
    assert np.linalg.norm(asked * response.weights) <= MOST_CORRECTION * 0.1 + 1e-12
