"""Control vector fields and Lie brackets from the C core (generated from sympy):
the thesis's values at its q0 (as corrected in docs/models.md), the non-slip
constraints, the growth vector, and the brackets against an independent Jacobian."""

import math
from dataclasses import replace

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from snakebot.model.kinematics import (
    KinematicsError,
    body_velocity,
    field_velocity,
    fields,
    wheel_speeds,
)
from snakebot.model.kinematics.model import singular_reason
from snakebot.model.robots import load_robot
from snakebot.model.symbolic import snake3 as sym_snake3
from snakebot.model.symbolic import trident as sym_trident

SNAKE3 = load_robot("snake3")
TRIDENT = load_robot("trident")
S3 = math.sqrt(3)
angle = st.floats(-1.4, 1.4)


def test_snake3_fields_at_the_thesis_q0():
    # Thesis (16), q0 = (0, 0, 0, pi/3, -pi/3), l = 1: models.md keeps these values.
    f = fields(SNAKE3, [0, 0, 0, math.pi / 3, -math.pi / 3])
    expected = {
        "g1": (0, 2 / 3, -2 / 3, 1, 0),
        "g2": (-S3 / 3, 1 / 3, -1 / 3, 0, 1),
        "h1": (2 / 3, 2 * S3 / 9, 0, 0, 0),
        "h2": (-2 * S3 / 27, -2 / 3, 2 / 9, 0, 0),
        "h3": (8 * S3 / 27, -4 / 9, 2 / 9, 0, 0),
    }
    for name, values in expected.items():
        np.testing.assert_allclose(f[name], values, atol=1e-9, err_msg=name)
    assert f.growth == (2, 3, 5) and not f.singular


def test_trident_fields_at_q0_with_the_corrected_h2():
    f = fields(TRIDENT, np.zeros(6))
    expected = {
        "g1": (1, 0, 0, -S3 / 2, 0, S3 / 2),
        "g2": (0, 1, 0, 1 / 2, -1, 1 / 2),
        "g3": (0, 0, 1, -2, -2, -2),
        "h1": (0, 0, 0, 1, 1, 1),
        "h2": (0, -1, 0, -1, 2, -1),  # the thesis prints the opposite sign
        "h3": (1, 0, 0, -S3, 0, S3),
    }
    for name, values in expected.items():
        np.testing.assert_allclose(f[name], values, atol=1e-9, err_msg=name)
    # The useful combinations of models.md.
    np.testing.assert_allclose(2 * f["g1"] - f["h3"], [1, 0, 0, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(f["g3"] + 2 * f["h1"], [0, 0, 1, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose((f["g1"] - f["h3"])[:3], 0, atol=1e-12)
    assert f.growth == (3, 6)
    assert f.det == pytest.approx(3 * S3 / 2, abs=1e-9)


def test_trident_forms_agree_on_inputs_but_not_brackets_at_q0():
    body, world = fields(TRIDENT, np.zeros(6), "body"), fields(TRIDENT, np.zeros(6), "world")
    for name in ("g1", "g2", "g3"):
        np.testing.assert_allclose(body[name], world[name], atol=1e-12)
    assert not np.allclose(body["h2"], world["h2"])


@settings(max_examples=60)
@given(
    st.tuples(
        st.floats(-3, 3), st.floats(-3, 3), st.floats(-math.pi, math.pi), angle, angle, angle
    ),
    st.floats(0.2, 3),
    st.floats(0.2, 3),
    st.sampled_from(["body", "world"]),
)
def test_trident_det_g_star_is_constant_in_both_forms(q, r, arm, form):
    robot = replace(TRIDENT, r=r, l=arm)
    f = fields(robot, np.array(q), form)
    assert f.det == pytest.approx(3 * S3 * r**2 / (2 * arm**6), rel=1e-12)
    # the closed form is the determinant of the fields the core computes
    assert np.linalg.det(f.values.T) == pytest.approx(f.det, rel=1e-7)
    assert f.growth == (3, 6)


def test_trident_without_base_radius_loses_rank():
    f = fields(replace(TRIDENT, r=0.0), np.array([0, 0, 0, 0.3, -0.2, 0.1]))
    assert f.det == 0.0 and f.growth[0] == 3 and f.growth[1] < 6


@settings(max_examples=60)
@given(
    st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(-math.pi, math.pi), angle, angle),
    st.floats(0.2, 3),
)
def test_snake3_det_g_star_is_l6_over_det_b4(q, half_link):
    robot = replace(SNAKE3, l=half_link)
    q = np.array(q)
    f = fields(robot, q)
    det_b = half_link * (math.sin(q[3]) - math.sin(q[4]) + math.sin(q[3] - q[4]))
    assert f.det_b == pytest.approx(det_b, rel=1e-9, abs=1e-15)
    if f.singular:
        assert f.det is None and abs(det_b) < 1e-11
        return
    assert f.det == pytest.approx(half_link**6 / det_b**4, rel=1e-12)
    if f.condition < 1e6:  # the numeric determinant is trustworthy there
        assert np.linalg.det(f.values.T) == pytest.approx(f.det, rel=1e-6)


@settings(max_examples=80)
@given(
    st.floats(-3.0, 3.0),
    st.floats(-9, -2.5),  # log10 of the distance from phi1 = phi2
    st.sampled_from([-1.0, 1.0]),
    st.floats(-math.pi, math.pi),
)
def test_snake3_growth_is_2_3_5_however_near_the_singular_line(p1, log_gap, sign, theta):
    q = np.array([0.4, -0.2, theta, p1, p1 + sign * 10**log_gap])
    f = fields(SNAKE3, q)
    assert not f.singular
    assert f.growth == (2, 3, 5)
    assert f.det > 0 and math.isfinite(f.det)
    # the conditioning reports the nearness: it grows as det B^-2
    far = fields(SNAKE3, np.array([0.4, -0.2, theta, p1, p1 + sign * 0.5]))
    assert f.condition > far.condition


def test_snake3_singular_set_and_its_reasons():
    on_line = fields(SNAKE3, np.array([0, 0, 0.3, 0.7, 0.7]))
    assert on_line.singular and on_line.values is None and on_line.growth is None
    assert singular_reason(SNAKE3, on_line.q) == "phi1 = phi2"
    folded = fields(SNAKE3, np.array([0, 0, 0, math.pi, 0.3]))
    assert folded.singular and singular_reason(SNAKE3, folded.q).startswith("phi1 = +-pi")
    folded = fields(SNAKE3, np.array([0, 0, 0, 0.3, -math.pi]))
    assert folded.singular and singular_reason(SNAKE3, folded.q).startswith("phi2 = +-pi")


def _constraint_residual(robot, q, qdot):
    normal, _ = wheel_speeds(robot, q, qdot)
    return np.abs(normal).max() / max(1.0, np.abs(qdot).max())


@settings(max_examples=80)
@given(
    st.tuples(
        st.floats(-3, 3), st.floats(-3, 3), st.floats(-math.pi, math.pi), angle, angle, angle
    ),
    st.sampled_from(["body", "world"]),
)
def test_every_field_and_bracket_of_the_trident_keeps_wheels_rolling_in_plane(q, form):
    # g_i satisfy the non-slip constraints by construction; brackets of fields in the
    # constraint distribution need not, so only g is checked here.
    f = fields(TRIDENT, np.array(q), form)
    for name in ("g1", "g2", "g3"):
        assert _constraint_residual(TRIDENT, q, f[name]) < 1e-12


@settings(max_examples=80)
@given(st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(-math.pi, math.pi), angle, angle))
def test_snake3_fields_satisfy_the_constraints(q):
    if abs(q[3] - q[4]) < 1e-2:
        return
    f = fields(SNAKE3, np.array(q))
    for name in ("g1", "g2"):
        assert _constraint_residual(SNAKE3, q, f[name]) < 1e-9


def _numeric_jacobian(func, q, step=1e-6):
    cols = []
    for k in range(len(q)):
        e = np.zeros(len(q))
        e[k] = step
        cols.append((func(q + e) - func(q - e)) / (2 * step))
    return np.array(cols).T


@pytest.mark.parametrize("robot,form", [(SNAKE3, None), (TRIDENT, "body"), (TRIDENT, "world")])
def test_brackets_match_an_independent_jacobian(robot, form):
    # Independent check (central differences on the C fields, tolerance 1e-6): the core
    # itself uses the exact Jacobians sympy generated.
    rng = np.random.default_rng(7)
    brackets = (
        {"h1": ("g1", "g2"), "h2": ("g1", "h1"), "h3": ("g2", "h1")}
        if robot is SNAKE3
        else {"h1": ("g1", "g2"), "h2": ("g1", "g3"), "h3": ("g2", "g3")}
    )
    for _ in range(5):
        q = rng.uniform(-1, 1, 3 + robot.n_joints)
        if robot is SNAKE3:
            q[4] = q[3] - 1.0  # well away from the singular line
        f = fields(robot, q, form)
        for h, (a, b) in brackets.items():

            def field_a(x, a=a):
                return fields(robot, x, form)[a]

            def field_b(x, b=b):
                return fields(robot, x, form)[b]

            expected = _numeric_jacobian(field_b, q) @ f[a] - _numeric_jacobian(field_a, q) @ f[b]
            np.testing.assert_allclose(f[h], expected, atol=1e-6 * max(1, abs(expected).max()))


def test_c_fields_equal_the_sympy_expressions():
    rng = np.random.default_rng(3)
    for model, robot, form in (
        (sym_snake3(), SNAKE3, None),
        (sym_trident("body"), TRIDENT, "body"),
        (sym_trident("world"), TRIDENT, "world"),
    ):
        params = [robot.l] if model.name == "snake3" else [robot.r, robot.l, *robot.alphas]
        symbols = [*model.q, *model.params]
        exprs = sp.Matrix.hstack(*model.fields.values())
        evaluate = sp.lambdify(symbols, exprs, "numpy")
        for _ in range(3):
            q = rng.uniform(-1, 1, len(model.q))
            if model.name == "snake3":
                q[4] = q[3] + 0.7
            expected = np.array(evaluate(*q, *params), dtype=float).T
            np.testing.assert_allclose(
                fields(robot, q, form).values, expected, rtol=1e-10, atol=1e-12
            )


@settings(max_examples=60)
@given(
    st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(-math.pi, math.pi), angle, angle),
    st.tuples(st.floats(-2, 2), st.floats(-2, 2)),
)
def test_quasi_static_model_equals_the_fields_for_snake3_with_free_rolling(q, u):
    # Two independent implementations: the quasi-static L1 solve and the sympy-generated
    # -B^-1 C. With free rolling (no rolling resistance, no axle friction) rolling costs
    # nothing and sliding does, so off the singular line the no-slip motion is the
    # unique least-dissipation motion. (With rolling resistance it stays so only while
    # the lateral forces it needs are within friction: near the line the wheels slide;
    # tests/sim/test_world_body.py.)
    if abs(q[3] - q[4]) < 0.05:
        return
    free = replace(SNAKE3.friction, rolling=0.0, axle_nm=0.0)
    bv = body_velocity(SNAKE3, np.array(q), np.array(u), free)
    qdot = field_velocity(SNAKE3, np.array(q), np.array(u))
    np.testing.assert_allclose(bv.xi, qdot[:3], atol=1e-8 * max(1, abs(qdot).max()))
    assert np.abs(bv.slip).max() < 1e-9 * max(1, abs(qdot).max())


@settings(max_examples=60)
@given(
    st.tuples(
        st.floats(-3, 3), st.floats(-3, 3), st.floats(-math.pi, math.pi), angle, angle, angle
    ),
    st.tuples(*[st.floats(-1, 1)] * 3),
)
def test_joint_driven_trident_recovers_the_body_inputs(q, u):
    # Drive the joints with the velocities the body inputs imply: with free-rolling wheels
    # (no rolling resistance) the body follows, as the no-slip fields say.
    free = replace(TRIDENT, friction=replace(TRIDENT.friction, rolling=0.0, axle_nm=0.0))
    qdot = field_velocity(TRIDENT, np.array(q), np.array(u), "body")
    try:
        bv = body_velocity(free, np.array(q), qdot[3:])
    except KinematicsError:
        return  # concurrent axles: the joint-driven model is singular there
    if bv.rcond < 1e-6:
        return
    np.testing.assert_allclose(bv.xi, qdot[:3], atol=1e-7)


def test_singular_configurations_are_reported_not_nan():
    """Free-rolling wheels leave the body velocity undetermined where the axles meet."""
    free = replace(SNAKE3, friction=replace(SNAKE3.friction, rolling=0.0, axle_nm=0.0))
    with pytest.raises(KinematicsError, match="singular configuration"):
        body_velocity(free, [0, 0, 0, 0.4, 0.4], [1.0, 0.0])
    with pytest.raises(KinematicsError, match="singular"):
        body_velocity(free, [0, 0, 0, 0, 0], [1.0, 0.5])  # straight: axles parallel
    at_rest = body_velocity(free, [0, 0, 0, 0, 0], [0.0, 0.0])
    assert at_rest.xi.tolist() == [0.0, 0.0, 0.0]
    # A trident whose three axles meet at the centre (r cos phi + l = 0).
    folded = replace(TRIDENT, r=2.0, l=1.0, friction=free.friction)
    phi = 2 * math.pi / 3
    with pytest.raises(KinematicsError, match="singular"):
        body_velocity(folded, [0, 0, 0, phi, phi, phi], [0.3, -0.1, 0.2])
    # Rolling resistance (the robots' own) makes both defined.
    assert np.isfinite(body_velocity(SNAKE3, [0, 0, 0, 0.4, 0.4], [1, 0]).xi).all()
    assert np.isfinite(
        body_velocity(
            replace(folded, friction=SNAKE3.friction), [0, 0, 0, phi, phi, phi], [0.3, -0.1, 0.2]
        ).xi
    ).all()


def test_the_c_core_sends_five_links_to_the_jet_model():
    with pytest.raises(KinematicsError, match="model fields"):
        fields(load_robot("snake5"), np.zeros(7))
