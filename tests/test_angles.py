"""The angle-wrapping rule and its entry-wise forms (:mod:`quatform.algebra.angles`)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quatform.algebra.angles import map_entries, wrap_angle, wrap_entries


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 7), max_size=8), st.integers(0, 2**32 - 1))
def test_wrap_entries_equals_the_in_place_wrap(angles, seed):
    e = np.random.default_rng(seed).uniform(-20.0, 20.0, (3, 8))
    want = e.copy()
    idx = sorted(set(angles))
    if idx:
        want[..., idx] = wrap_angle(want[..., idx])
    got = wrap_entries(e, angles)
    assert np.array_equal(got, want)


def test_wrap_range_and_boundary():
    a = np.array([-np.pi, np.pi, 3 * np.pi, -3 * np.pi + 1e-12, 0.0])
    w = wrap_angle(a)
    assert np.all(w >= -np.pi) and np.all(w < np.pi)
    assert np.allclose(np.cos(w), np.cos(a), atol=1e-12) and np.allclose(np.sin(w), np.sin(a), atol=1e-12)


def test_map_entries_runs_and_jax():
    e = np.arange(8.0).reshape(1, 8)
    out = map_entries(e, [2, 3, 7], lambda a, b: -e[..., a:b])
    assert out.tolist() == [[0, 1, -2, -3, 4, 5, 6, -7]]
    jnp = pytest.importorskip("jax.numpy")
    import jax

    with jax.enable_x64(True):
        x = np.random.default_rng(1).uniform(-9, 9, (4, 8))
        got = jax.jit(lambda v: wrap_entries(v, [3, 7]))(jnp.asarray(x))
        assert np.array_equal(np.asarray(got), wrap_entries(x, [3, 7]))


def test_winding_a_half_turn_is_the_same_whatever_its_rounding():
    """A yaw exactly half a turn from its reference, or a few ulp short of it (what another
    backend's rounding gives), is wound the same way: to +pi from the reference's side."""
    import math

    from quatform.algebra.angles import TIE_TURNS
    from quatform.formations.base import PAIR_LAYOUT
    from quatform.formations.dual_quaternion_team import dq_align_yaws

    for t in (math.pi, math.nextafter(math.pi, 0.0), math.pi - 4e-16, 3 * math.pi, -math.pi):
        r = np.zeros(8)
        ref = np.zeros(8)
        ref[[3, 7]] = t
        wound = PAIR_LAYOUT.wind(r, ref)  # the float path
        batch = PAIR_LAYOUT.wind(r[None], ref[None])[0]  # the array path
        aligned = dq_align_yaws(tuple(r.tolist()), t, t)
        want = r[3] + 2 * math.pi * math.floor(t / (2 * math.pi) + 0.5 + 0.5 * TIE_TURNS)
        assert wound[3] == batch[3] == aligned[3] == want
        assert -math.pi < wound[3] - t <= math.pi + 1e-12
    # a real difference (not a rounding of half a turn) keeps the rule (-pi, pi]
    r, ref = np.zeros(8), np.zeros(8)
    ref[3] = math.pi - 1e-9
    assert PAIR_LAYOUT.wind(r, ref)[3] == 0.0


def test_the_error_quaternions_half_turn_tie():
    """qe_0 within HALF_TURN_TIE of 0 is read as 0 (sgn = +1): the law's rate is the same for
    the roundings of a half turn either side of it."""
    from quatform.control.laws import HALF_TURN_TIE, quaternion_feedback

    rates = []
    for w in (0.0, 6e-17, -6e-17, -0.5 * HALF_TURN_TIE):
        q = (w, 0.0, 0.0, float(np.sqrt(1.0 - w * w)))
        rates.append(quaternion_feedback(q, (1.0, 0.0, 0.0, 0.0), (0.0,) * 4, (1.0, 1.0, 1.0), 0.0)[1])
    np.testing.assert_allclose(rates, [rates[0]] * 4, atol=1e-12)  # the same way: w driven up
    q = (-2 * HALF_TURN_TIE, 0.0, 0.0, 1.0)  # beyond the tie: the other way
    other = quaternion_feedback(q, (1.0, 0.0, 0.0, 0.0), (0.0,) * 4, (1.0, 1.0, 1.0), 0.0)[1]
    assert rates[0][0] == pytest.approx(0.5) and other[0] == pytest.approx(-0.5, abs=1e-9)
