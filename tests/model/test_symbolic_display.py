"""`model fields --symbolic`'s expressions of the 3-link snake: equal to the fields they
show, each over a power of the determinant, the same and quick whatever the hash seed
(sympy's trigsimp, used before, took 15 s to more than 240 s depending on it)."""

from __future__ import annotations

import os
import random
import subprocess
import sys

import pytest

sp = pytest.importorskip("sympy")
import mpmath  # noqa: E402  (sympy's own dependency)

from snakebot.model.robots import load_robot  # noqa: E402
from snakebot.model.symbolic.display import field_expressions  # noqa: E402

pytestmark = [pytest.mark.timeout(120), pytest.mark.late]


def test_the_snake3_expressions_equal_its_fields_over_a_power_of_the_determinant():
    ex = field_expressions(load_robot("snake3"))
    model = ex.model
    x, y, theta, p1, p2 = model.q
    det = model.det_b / model.params[0]
    rng = random.Random(3)
    symbols = (p1, p2, model.params[0], theta, x, y)
    for name, vec in model.fields.items():
        for shown, field in zip(ex.components[name], vec, strict=True):
            # evaluated by mpmath at 30 digits (sympy's subs and N at 20 took 9 of the
            # test's 14 CPU seconds)
            want_at, got_at = (sp.lambdify(symbols, e, "mpmath") for e in (field, shown))
            with mpmath.workdps(30):
                for _ in range(4):  # four points of its own for each component
                    a1, a2 = rng.uniform(-1.2, 1.2), rng.uniform(-1.2, 1.2)
                    want = complex(want_at(a1, a2, 0.7, 0, 0.3, -0.2))
                    got = complex(got_at(a1, a2, 0.7, 0, 0.3, -0.2))
                    assert abs(got - want) <= 1e-12 * max(1.0, abs(want)), (name, shown)
            for factor in sp.Mul.make_args(sp.fraction(shown)[1]):  # a number, det's powers
                assert factor.is_number or factor.as_base_exp()[0] == det, (name, shown)
    # the brackets of order three hold the determinant's cube, shown as such
    assert all(sp.fraction(c)[1] == det**3 for c in ex.components["h3"][:3])


def test_the_same_text_whatever_the_hash_seed():
    """Two hash seeds that made trigsimp take 48 s and 67 s give the same text, each
    within the test's timeout."""
    outputs = []
    for seed in ("4", "5"):
        env = os.environ | {"PYTHONHASHSEED": seed}
        done = subprocess.run(
            [sys.executable, "-m", "snakebot", "model", "fields", "snake3", "--symbolic"],
            env=env,
            capture_output=True,
            text=True,
            timeout=50,
            check=True,
        )
        outputs.append(done.stdout)
    assert outputs[0] == outputs[1]
    assert "(sin(phi1) - sin(phi2) + sin(phi1 - phi2))**3" in outputs[0]
