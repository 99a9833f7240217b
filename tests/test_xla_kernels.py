"""The array kernels that shape XLA's CPU programs: :func:`quatform.algebra.kernels.hold` and
:func:`quatform.algebra.kernels.small_matmul` give NumPy's values on JAX."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quatform.algebra.kernels import hold, small_matmul


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), k=st.sampled_from([1, 2, 3, 4, 5, 7, 16, 101, 707]))
def test_hold_is_its_operand_bitwise(seed, k):
    jax = pytest.importorskip("jax")
    a = np.random.default_rng(seed).normal(size=(3, 2, k)) * 10.0 ** np.random.default_rng(seed).integers(-300, 300)
    assert hold(a) is a  # NumPy: the array itself
    with jax.enable_x64(True):
        got = np.asarray(jax.jit(hold)(jax.numpy.asarray(a)))
    assert got.shape == a.shape and np.array_equal(got, a)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), m=st.integers(1, 5), k=st.integers(1, 6), n=st.integers(1, 5),
       lead=st.sampled_from([(), (1,), (4,), (2, 3)]))
def test_small_matmul_is_matmul(seed, m, k, n, lead):
    jax = pytest.importorskip("jax")
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=lead + (m, k)), rng.normal(size=(k, n))  # b broadcast over the batch
    want = a @ b
    np.testing.assert_array_equal(small_matmul(a, b), want)
    with jax.enable_x64(True):
        got = np.asarray(jax.jit(small_matmul)(jax.numpy.asarray(a), jax.numpy.asarray(b)))
    scale = np.abs(a)[..., :, :, None] * np.abs(b)[..., None, :, :]  # the sum's conditioning
    np.testing.assert_allclose(got, want, rtol=0, atol=8 * k * np.finfo(float).eps * scale.sum(axis=-2).max())
