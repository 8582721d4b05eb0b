"""Fields and brackets from jets (kinematics/lie.py): the N-link snake's two control
fields keep every wheel rolling, equal the C core's 3-link fields and brackets, agree
with an independent finite-difference bracket, and give the growth vectors of
docs/models.md; the car of the thesis's first chapter; the jets' derivatives."""

import math
from dataclasses import replace

import numpy as np
import pytest
import sympy as sp
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from snakebot.model.kinematics import fields, wheel_speeds
from snakebot.model.kinematics.jets import JetSpace
from snakebot.model.kinematics.lie import LieError, lie_fields, lie_model, lyndon_words
from snakebot.model.robots import load_robot

SNAKE3, SNAKE5, CAR = load_robot("snake3"), load_robot("snake5"), load_robot("car")
angle = st.floats(-1.4, 1.4)


def snake(links: int):
    joint = SNAKE5.joints[0]
    joints = tuple(replace(joint, name=f"phi{k + 1}", servo_id=k + 1) for k in range(links - 1))
    return replace(SNAKE5, name=f"snake{links}", links=links, joints=joints)


def test_lyndon_basis_has_the_free_lie_algebra_dimensions():
    words = lyndon_words(2, 6)
    assert [sum(len(w) == k for w in words) for k in range(1, 7)] == [2, 1, 2, 3, 6, 9]


def test_jets_carry_exact_taylor_coefficients():
    x, y = sp.symbols("x y")
    expr = sp.sin(x) * sp.cos(y) / (2 + x * y) + sp.cos(x - y) ** 2
    space = JetSpace(2, 4)
    at = (0.7, -0.4)
    jx, jy = space.variable(0, at[0]), space.variable(1, at[1])
    jet = jx.sin() * jy.cos() / (2 + jx * jy) + (jx - jy).cos() * (jx - jy).cos()
    d = jet.diff(0).diff(1).diff(1)  # d^3 / dx dy^2, a degree-1 jet
    exact = sp.diff(expr, x, y, y)
    assert d.value == pytest.approx(float(exact.subs({x: at[0], y: at[1]})), rel=1e-12)
    assert d.diff(0).value == pytest.approx(
        float(sp.diff(exact, x).subs({x: at[0], y: at[1]})), rel=1e-12
    )


@settings(max_examples=40)
@given(st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(-math.pi, math.pi), angle, angle))
def test_three_links_equal_the_c_core(q):
    q = np.array(q)
    assume(abs(q[3] - q[4]) > 1e-3)
    c = fields(SNAKE3, q)
    jets = lie_fields(lie_model(SNAKE3), q, 3)
    scale = np.abs(c.values).max(axis=1)
    for name, sign, jet_name in (
        ("g1", 1, "g1"),
        ("g2", 1, "g2"),
        ("h1", 1, "[g1,g2]"),
        ("h2", 1, "[g1,[g1,g2]]"),
        ("h3", -1, "[[g1,g2],g2]"),  # [[g1,g2],g2] = -[g2,[g1,g2]]
    ):
        k = c.names.index(name)
        np.testing.assert_allclose(jets[jet_name], sign * c[name], atol=1e-9 * scale[k])
    assert jets.growth == (2, 3, 5)


@settings(max_examples=30)
@given(st.integers(3, 16), st.data())
def test_n_link_fields_keep_every_wheel_rolling(links, data):
    robot = snake(links)
    phi = data.draw(st.lists(angle, min_size=links - 1, max_size=links - 1))
    theta = data.draw(st.floats(-math.pi, math.pi))
    assume(abs(phi[0] - phi[1]) > 1e-2)
    q = np.r_[0.3, -0.1, theta, phi]
    lf = lie_fields(lie_model(robot), q, 2)
    for name in ("g1", "g2"):
        normal, _ = wheel_speeds(robot, q, lf[name])
        assert np.abs(normal).max() < 1e-9 * max(1.0, np.abs(lf[name]).max())
    np.testing.assert_array_equal(lf["g1"][3:5], [1, 0])
    np.testing.assert_array_equal(lf["g2"][3:5], [0, 1])


def test_five_link_bracket_matches_a_finite_difference_jacobian():
    model = lie_model(SNAKE5)
    q = np.array([0.1, 0.2, 0.3, 0.5, -0.3, 0.4, -0.2])

    def field(name, at):
        return lie_fields(model, at, 1)[name]

    def jacobian(name):
        h = 1e-6
        cols = [(field(name, q + h * e) - field(name, q - h * e)) / (2 * h) for e in np.eye(7)]
        return np.array(cols).T

    expected = jacobian("g2") @ field("g1", q) - jacobian("g1") @ field("g2", q)
    np.testing.assert_allclose(lie_fields(model, q, 2)["[g1,g2]"], expected, atol=1e-6)


@settings(max_examples=60)
@given(
    st.integers(3, 9),
    st.floats(-1.2, 1.2),
    st.floats(-9, -1),  # log10 of the distance from phi1 = phi2
    st.sampled_from([-1.0, 1.0]),
    st.floats(-math.pi, math.pi),
)
def test_growth_to_depth_3_is_exact_however_near_the_singular_set(links, p1, log_gap, sign, theta):
    others = np.linspace(0.4, -0.3, links - 3)
    q = np.r_[0.1, 0.2, theta, p1, p1 + sign * 10**log_gap, others]
    lf = lie_fields(lie_model(snake(links)), q, 3)
    assert not lf.singular
    assert lf.growth == (2, 3, 5) and lf.ranks_reliable
    assert lf.condition > 1 / 10**log_gap  # it reports the nearness


def test_deeper_ranks_are_flagged_where_double_precision_cannot_decide():
    q = np.array([0, 0, 0, 0.3, 0.35, -0.2, 0.4])
    clear = lie_fields(lie_model(SNAKE5), q, 5)
    assert clear.growth == (2, 3, 5, 6, 7) and clear.ranks_reliable
    for gap in (1e-1, 1e-2, 1e-3):  # trusted, and right
        q[4] = 0.3 + gap
        near = lie_fields(lie_model(SNAKE5), q, 5)
        assert near.ranks_reliable and near.growth == (2, 3, 5, 6, 7)
    for gap in (1e-4, 1e-6, 1e-9):  # the deeper brackets have lost their digits
        q[4] = 0.3 + gap
        near = lie_fields(lie_model(SNAKE5), q, 5)
        assert not near.ranks_reliable and near.growth[:3] == (2, 3, 5)


def test_n_link_growth_vectors():
    q4 = np.array([0, 0, 0.2, 0.6, -0.3, 0.4])
    assert lie_fields(lie_model(snake(4)), q4, 4).growth == (2, 3, 5, 6)  # all of R^6
    q5 = np.array([0, 0, 0.2, 0.3, -0.2, 0.4, 0.1])
    assert lie_fields(lie_model(SNAKE5), q5, 3).growth == (2, 3, 5)


def test_n_link_singular_set_is_the_first_two_joints():
    for links in (4, 5, 9):
        phi = np.linspace(-0.5, 0.7, links - 1)
        phi[1] = phi[0]
        assert lie_fields(lie_model(snake(links)), np.r_[0, 0, 0, phi], 2).singular
        phi[1] = phi[0] - 0.05
        assert not lie_fields(lie_model(snake(links)), np.r_[0, 0, 0, phi], 2).singular


@settings(max_examples=40)
@given(st.floats(-math.pi, math.pi), st.floats(-1.5, 1.5), st.floats(0.2, 3))
def test_car_fields_are_the_thesis_s(theta, steer, wheelbase):
    car = replace(CAR, l=wheelbase)
    lf = lie_fields(lie_model(car), np.array([0.5, -1.0, theta, steer]), 3)
    sec2 = 1 / (wheelbase * math.cos(steer) ** 2)
    np.testing.assert_allclose(lf["S"], [0, 0, 0, 1])
    np.testing.assert_allclose(
        lf["D"], [math.cos(theta), math.sin(theta), math.tan(steer) / wheelbase, 0]
    )
    np.testing.assert_allclose(lf["R"], [0, 0, sec2, 0], rtol=1e-12)
    np.testing.assert_allclose(
        lf["T"], [-math.sin(theta) * sec2, math.cos(theta) * sec2, 0, 0], rtol=1e-12, atol=1e-12
    )
    assert lf["[S,D]"] is not None and lf.growth == (2, 3, 4)
    frame = np.array([lf[n] for n in ("S", "D", "R", "T")]).T
    assert np.linalg.det(frame) == pytest.approx(sec2**2, rel=1e-9)  # the exact criterion


def test_car_is_singular_with_the_wheels_across():
    assert lie_fields(lie_model(CAR), np.array([0, 0, 0, math.pi / 2]), 3).singular


def test_depth_is_bounded():
    with pytest.raises(LieError, match="between 1 and 8"):
        lie_fields(lie_model(SNAKE5), np.array([0, 0, 0, 0.3, -0.2, 0, 0]), 9)
    with pytest.raises(LieError, match="ask for depth 5 or less"):
        lie_fields(lie_model(snake(16)), np.r_[0, 0, 0, np.linspace(0.3, -0.3, 15)], 6)


def test_car_jets_equal_the_sympy_model():
    from snakebot.model.symbolic.models import car as sym_car

    model = sym_car()
    q = (0.3, -0.4, 0.9, -0.6)
    subs = dict(zip(model.q, q, strict=True)) | {model.params[0]: CAR.l}
    lf = lie_fields(lie_model(CAR), np.array(q), 3)
    for name in ("S", "D", "R", "T"):
        exact = np.array([float(c.subs(subs)) for c in model.fields[name]])
        np.testing.assert_allclose(lf[name], exact, rtol=1e-12, atol=1e-15)
