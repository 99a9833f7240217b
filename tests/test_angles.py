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
