"""The core's batch sine and cosine (kin_sincos, firmware/core/kin_trig.c) agree with
libm's within 2 units in the last place over the whole range it reduces itself, and hand
larger and non-finite angles to libm unchanged."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from snakebot.core import ffi, lib

REDUCED = 2**19 * math.pi / 2  # largest angle reduced in the core (REDUCE_MAX)


def padded(n: int) -> int:
    return -(-n // lib.KIN_TRIG_BLOCK) * lib.KIN_TRIG_BLOCK


def core_sincos(angles: list[float]) -> tuple[np.ndarray, np.ndarray]:
    size = padded(len(angles))
    x = np.zeros(size)
    x[: len(angles)] = angles
    sn, cs = np.full(size, np.nan), np.full(size, np.nan)
    ptr = lambda a: ffi.cast("double *", ffi.from_buffer(a))  # noqa: E731
    lib.kin_sincos(len(angles), ptr(x), ptr(sn), ptr(cs))
    return sn[: len(angles)], cs[: len(angles)]


def ulps(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    return np.abs(got - want) / np.spacing(np.abs(want))


angles = st.one_of(
    st.floats(-7.0, 7.0),  # joint angles and headings
    st.floats(-1e-3, 1e-3),  # tiny: sin x ~ x to the last bit
    st.floats(-REDUCED, REDUCED),  # long times: omega t
)


@settings(max_examples=300, deadline=None)
@given(st.lists(angles, min_size=1, max_size=17))
def test_within_two_ulps_of_libm(xs):
    sn, cs = core_sincos(xs)
    assert ulps(sn, np.array([math.sin(x) for x in xs])).max() <= 2.0
    assert ulps(cs, np.array([math.cos(x) for x in xs])).max() <= 2.0


def test_every_quadrant_and_its_boundaries():
    # k pi / 4 and its neighbours: where the quadrant (swap and signs) changes
    base = np.arange(-16, 17) * (math.pi / 4)
    xs = np.concatenate((base, np.nextafter(base, np.inf), np.nextafter(base, -np.inf)))
    sn, cs = core_sincos(list(xs))
    np.testing.assert_allclose(sn, np.sin(xs), rtol=0, atol=2.3e-16)
    np.testing.assert_allclose(cs, np.cos(xs), rtol=0, atol=2.3e-16)


def test_large_and_non_finite_angles_are_libms():
    xs = [REDUCED * 1.01, -1e12, 1e300, math.inf, -math.inf, math.nan, 0.5]
    sn, cs = core_sincos(xs)
    for x, s, c in zip(xs[:3], sn, cs, strict=False):
        assert (s, c) == (math.sin(x), math.cos(x))
    assert np.isnan(sn[3:6]).all() and np.isnan(cs[3:6]).all()
    assert ulps(sn[6:], np.array([math.sin(0.5)])).max() <= 2.0
