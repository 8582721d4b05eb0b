"""The serpenoid closed loop's parts (``snakebot.model.plan.serpenoid_goto``): the wave played
cycle by cycle, the body's middle, the learned cycle and the plans of whole cycles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snakebot.model.plan import se2
from snakebot.model.plan.planner import Tolerance
from snakebot.model.plan.serpenoid_goto import (
    ACCEPT,
    FRAMES_PER_CYCLE,
    HORIZON,
    MAX_CHANGE,
    MAX_OFFSET,
    TWO_REVERSALS,
    CycleModel,
    Wave,
    arc,
    end_of,
    finishing_fraction,
    link1_from_middle,
    middle,
    plan_cycles,
    ways_of,
)
from snakebot.model.robots import load_robot
from snakebot.workflows.goto import uses_serpenoid

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


def test_the_model_learns_the_floor_from_its_cycles():
    truth = CycleModel(np.array([0.105, -0.02, -0.01, -0.08, 0.004, 0.46, 0.30]))
    model = CycleModel.from_geometry(SNAKE5, 0.08)
    rng = np.random.default_rng(5)
    p = 0.0
    for _ in range(40):
        q, way = float(rng.uniform(-MAX_OFFSET, MAX_OFFSET)), float(rng.choice([-1.0, 1.0]))
        model.add(q, p, way, truth.motion(q, p, way))
        p = q
    # forty cycles outweigh the prior: the straight cycle's length and the turn's
    # share of this cycle's and the last one's offset are the floor's
    assert model.length(0.0, 0.0) == pytest.approx(truth.length(0.0, 0.0), rel=0.02)
    assert model.coefficients[5:] == pytest.approx(truth.coefficients[5:], abs=0.02)
    prior = CycleModel.from_geometry(SNAKE5, 0.08)
    for q, p in ((0.5, 0.5), (-0.3, 0.2), (0.0, -0.6)):
        want = truth.motion(q, p, -1.0)
        learned = np.abs(model.motion(q, p, -1.0) - want).max()
        assert learned < 0.01 and learned < 0.3 * np.abs(prior.motion(q, p, -1.0) - want).max()


def test_a_cycle_backwards_retraces_the_arc_forwards():
    model = CycleModel.from_geometry(SNAKE5, 0.1)
    forwards = model.motion(0.4, 0.4, 1.0)
    assert forwards[2] > 0  # a positive offset turns the body left
    assert se2.compose(forwards, model.motion(0.4, 0.4, -1.0)) == pytest.approx(np.zeros(3))


def test_the_ways_to_drive_reverse_at_most_twice():
    for n in range(1, 9):
        ways = ways_of(n)
        assert len(set(ways)) == len(ways)
        assert all(len(w) == n for w in ways)
        reversals = [sum(a != b for a, b in zip(w[:-1], w[1:], strict=True)) for w in ways]
        assert max(reversals) == min(n - 1, 1 if n > TWO_REVERSALS else 2)


def _link1(q):
    return (-0.35, 0.0, -2.0 * q)  # link 1 behind the middle, turned against the bend


def test_end_of_composes_the_cycles_arcs():
    model = CycleModel.from_geometry(SNAKE5, 0.1)
    here = np.array([0.2, -0.1, 0.3])
    ways, offsets = (1.0, 1.0, -1.0), np.array([0.2, -0.3, 0.1])
    pose, p = here, 0.05
    for way, q in zip(ways, offsets, strict=True):
        pose = se2.compose(pose, model.motion(float(q), p, way))
        p = float(q)
    expected = se2.compose(pose, np.array(_link1(p)))
    assert end_of(model, here, 0.05, ways, offsets, _link1) == pytest.approx(expected)


@pytest.mark.parametrize("goal", [(0.5, 0.2, 0.6), (-0.3, 0.1, -0.4), (0.05, 0.3, 1.0)])
def test_the_planned_cycles_reach_the_pose_by_the_model(goal):
    model = CycleModel.from_geometry(SNAKE5, 0.105)
    tol = Tolerance(0.01, math.radians(2))
    start = se2.inverse(np.array(_link1(0.0)))  # link 1 at the origin
    plan = plan_cycles(model, start, 0.0, np.array(goal), tol, _link1)
    assert plan.miss <= ACCEPT
    end = end_of(model, start, 0.0, plan.ways, np.array(plan.offsets), _link1)
    assert math.hypot(end[0] - goal[0], end[1] - goal[1]) <= ACCEPT * tol.position * 1.01
    offsets = np.r_[0.0, plan.offsets]
    assert np.all(np.abs(offsets) <= MAX_OFFSET + 1e-9)
    assert np.all(np.abs(np.diff(offsets)) <= MAX_CHANGE + 0.05)
    # the fewest cycles: the straight way there takes at least this many
    assert len(plan.ways) >= math.hypot(goal[0], goal[1]) / model.length(0.0, 0.0) - 1


@pytest.mark.parametrize("straight", [0.004, 0.0, -0.01])
def test_a_model_that_learned_short_cycles_still_plans_the_nearest_it_can(straight):
    """`sim goto snake5 --world mujoco` at seed 34 once learned a straight cycle so short
    that the goal lay more than HORIZON cycles away: the search started past HORIZON,
    found no plan at all, and goto stopped with an internal error."""
    model = CycleModel(np.array([straight, 0.0, 0.0, 0.0, 0.0, 0.2, 0.2]))
    start = se2.inverse(np.array(_link1(0.0)))
    goal = np.array([-0.63, -0.02, -0.54])
    plan = plan_cycles(model, start, 0.0, goal, Tolerance(0.01, math.radians(2)), _link1)
    assert len(plan.ways) == HORIZON
    assert math.isfinite(plan.miss)


def test_only_n_link_snakes_on_a_physics_world_steer_waves():
    assert uses_serpenoid(SNAKE5, "mujoco")
    assert not uses_serpenoid(SNAKE5, "kinematic")
    assert not uses_serpenoid(load_robot("snake3"), "mujoco")
    assert not uses_serpenoid(load_robot("trident"), "mujoco")


def test_link1_table_interpolates_as_numpy_does():
    # the plans depend on these values to the last bit: a closed loop's outcome at a
    # seed turns on tiny differences
    rng = np.random.default_rng(3)
    table = link1_from_middle(Wave(SNAKE5), rng.normal(0.0, 0.05, SNAKE5.n_joints))
    grid, columns = np.array(table.grid), np.array(table.rows).T
    for q in [*rng.uniform(-0.7, 0.7, 2000), *grid, 0.0, 5.0, -5.0]:
        assert table(q) == tuple(float(np.interp(q, grid, c)) for c in columns)


@pytest.mark.parametrize("fraction", [0.37, -0.12])
def test_a_fraction_that_ends_at_the_goal_by_the_model_is_found(fraction):
    """The fraction of a cycle whose end the model puts at the goal is the one chosen
    (the middle along the held offset's arc in proportion, link 1 placed by the shape at
    the phase it leaves); a goal that no fraction at that offset reaches gives none."""
    model = CycleModel.from_geometry(SNAKE5, 0.105)
    wave = Wave(SNAKE5, offset=0.2)
    lag = np.array([0.02, -0.01, 0.03, 0.0])
    here = np.array([0.1, -0.2, 0.4])
    moved = se2.compose(
        here, arc(fraction * model.turn(0.2, 0.2), fraction * model.length(0.2, 0.2))
    )
    shape = wave.angles_at(2 * math.pi * fraction, 0.2) + lag
    goal = se2.compose(moved, se2.inverse(middle(SNAKE5, shape)))
    tol = Tolerance(0.004, math.radians(2))
    found = finishing_fraction(model, wave, here, lag, goal, tol)
    assert found is not None and found[0] == pytest.approx(fraction) and found[1] < 1e-6
    aside = se2.compose(goal, np.array([0.0, 0.05, 0.0]))
    assert finishing_fraction(model, wave, here, lag, aside, tol) is None
