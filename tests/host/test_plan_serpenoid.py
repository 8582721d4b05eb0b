"""The serpenoid closed loop's parts (``snakebot.plan.serpenoid_goto``): the wave played
segment by segment, the body's middle, the learned response and the car's path."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snakebot.plan import se2
from snakebot.plan.goto import uses_serpenoid
from snakebot.plan.serpenoid_goto import (
    FRAMES_PER_CYCLE,
    MAX_OFFSET,
    CycleModel,
    Wave,
    middle,
    plan_moves,
    predict,
)
from snakebot.robots import load_robot

SNAKE5 = load_robot("snake5")


def test_segments_join_and_carry_the_phase_on():
    wave = Wave(SNAKE5)
    a = wave.frames(0.0, 0.5)
    b = wave.frames(0.3, 0.25)
    c = wave.frames(0.3, -0.25)
    assert len(a) == FRAMES_PER_CYCLE // 2 + 1
    # each segment starts where the last ended: no jump for the servos
    assert np.allclose(a[-1], b[0]) and np.allclose(b[-1], c[0])
    # the offset is blended in over the first quarter cycle and then held
    phase = wave.phase + 2 * math.pi * 0.25
    assert np.allclose(b[-1], Wave(SNAKE5).angles_at(phase, 0.3))
    assert np.allclose(b[0], Wave(SNAKE5).angles_at(phase - 2 * math.pi * 0.25, 0.0))
    # backwards retraces the wave: a quarter cycle back ends where the forward one began
    assert np.allclose(c[-1], b[0] + 0.3)
    lo, hi = np.radians(-90), np.radians(90)
    assert np.all((np.vstack([a, b, c]) > lo) & (np.vstack([a, b, c]) < hi))


def test_the_wave_at_its_largest_offsets_is_within_the_limits():
    Wave(SNAKE5).check()


def test_middle_of_a_straight_and_a_bent_body():
    straight = middle(SNAKE5, np.zeros(SNAKE5.n_joints))
    assert straight == pytest.approx([SNAKE5.links * SNAKE5.l, 0.0, 0.0])
    q = 0.2
    bent = middle(SNAKE5, np.full(SNAKE5.n_joints, q))
    # the links' mean heading: link k is turned by (k - 1) q from link 1
    assert bent[2] == pytest.approx(q * (SNAKE5.links - 1) / 2)
    # bent to the left, the middle lies to the left of link 1's line
    assert bent[1] > 0 and bent[0] < straight[0]


def test_the_model_learns_the_floor_from_its_segments():
    truth = CycleModel(0.38, np.array([0.05, 2.2, 0.4]))
    model = CycleModel(0.3, np.array([0.0, 1.0, 0.0]))
    rng = np.random.default_rng(5)
    offset = 0.0
    for _ in range(25):
        q, c = float(rng.uniform(-0.3, 0.3)), float(rng.choice([-0.5, 0.5]))
        moved = truth.motion(q, c, q - offset)
        model.add(q, c, q - offset, moved)
        offset = q
    assert model.distance == pytest.approx(truth.distance, rel=0.05)
    # the bias and the change's turn are learned; the gain per offset (which half-cycle
    # segments at offsets of at most 0.3 say little about) stays drawn to the prior
    # from the geometry, but moves towards the floor's
    miss = np.abs(model.coefficients - truth.coefficients) / np.abs(
        model.prior - truth.coefficients
    )
    assert miss[0] < 0.2 and miss[2] < 0.2 and miss[1] < 0.7


@pytest.mark.parametrize("remaining", [(0.5, 0.2, 0.6), (-0.3, 0.1, -0.4), (0.05, 0.3, 1.0)])
def test_the_planned_moves_reach_the_pose_by_the_model(remaining):
    model = CycleModel(0.38, np.array([0.0, 2.2, 0.3]))
    goal = np.array(remaining)
    moves = plan_moves(model, 0.0, goal, 0.7)
    assert np.all(np.abs(moves[:, 0]) <= MAX_OFFSET + 1e-9)
    end = predict(model, 0.0, moves)
    assert np.hypot(*(end[:2] - goal[:2])) < 0.005
    assert abs((end[2] - goal[2] + math.pi) % (2 * math.pi) - math.pi) < 0.01
    # and the pose it reaches composes as the moves' motions do
    one_by_one = np.zeros(3)
    offset = 0.0
    for q, c in moves:
        one_by_one = se2.compose(one_by_one, model.motion(q, c, q - offset))
        offset = q
    assert one_by_one == pytest.approx(end)


def test_only_n_link_snakes_on_a_physics_world_steer_waves():
    assert uses_serpenoid(SNAKE5, "mujoco")
    assert not uses_serpenoid(SNAKE5, "kinematic")
    assert not uses_serpenoid(load_robot("snake3"), "mujoco")
    assert not uses_serpenoid(load_robot("trident"), "mujoco")
