"""docs/thesis.md's explanation of g2, demonstrated: before phi3 reaches its joint limit
(1.86 s), the joint path of the trident's g2 passes close to a singular configuration of
the joint-driven model at about 1.59 s, where the three wheels' axles nearly meet in one
point: the sticking rows' condition collapses there and recovers after. Between the two,
what the joints ask is a motion the non-slip wheels barely determine, so both worlds
leave the model's path before any joint is clipped."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from snakebot.model.kinematics import body_velocity
from snakebot.model.robots import load_robot
from snakebot.workflows.thesis import RUNS, thesis_table

TRIDENT = load_robot("trident")
# free-rolling wheels: the joint-driven model's own determinacy, no rolling resistance
FREE = replace(TRIDENT, friction=replace(TRIDENT.friction, rolling=0.0, axle_nm=0.0))


def conditions():
    """Frame times, the model's states and the sticking rows' reciprocal condition
    number at each frame of g2 (the joints' velocity by central differences)."""
    run = next(r for r in RUNS if r.name == "g2")
    _, t, q, clipped = thesis_table(run, TRIDENT)
    assert clipped == 7  # the frames past phi3's limit
    rcond = []
    for k in range(len(t)):
        dphi = q[min(k + 1, len(t) - 1), 3:] - q[max(k - 1, 0), 3:]
        rcond.append(body_velocity(FREE, q[k], dphi).rcond)
    return t, q, np.array(rcond)


def test_g2_passes_a_singular_configuration_before_the_joint_limit():
    t, q, rcond = conditions()
    worst = int(np.argmin(rcond))
    assert 1.55 <= t[worst] <= 1.65
    assert rcond[worst] < 0.01 * rcond[0]  # from 0.27 at the start to about 1e-3
    limit = int(np.argmax(q[:, 5] > TRIDENT.joints[2].max_rad))
    assert 1.84 <= t[limit] <= 1.88
    assert t[worst] < t[limit] and rcond[limit] > 10 * rcond[worst]  # it has recovered
