"""Group axioms and identities of the quaternion algebra, on batches (hypothesis)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, strategies as st

from quatform.algebra import (
    IDENTITY,
    axis_angle_from_q,
    matrix_from_q,
    q_angle,
    q_angle_between,
    q_from_axis_angle,
    q_from_matrix,
    qconj,
    qexp,
    qinv,
    qlog,
    qmul,
    qnorm,
    qnormalize,
    qpow,
    qrotate,
    qslerp,
)

from conftest import quaternions, random_unit_quaternions, same_shape, unit_quaternions, vectors

TOL = 1e-9


def _hamilton_reference(q, p):
    """seed 001 eq. (2.18), written independently of the kernel."""
    q0, qv = q[..., :1], q[..., 1:]
    p0, pv = p[..., :1], p[..., 1:]
    w = q0 * p0 - np.sum(qv * pv, axis=-1, keepdims=True)
    v = q0 * pv + p0 * qv + np.cross(qv, pv)
    return np.concatenate([w, v], axis=-1)


@given(same_shape(quaternions, quaternions))
def test_product_matches_vector_form(qp):
    q, p = qp
    np.testing.assert_allclose(qmul(q, p), _hamilton_reference(q, p), atol=1e-12, rtol=1e-12)


def test_basis_products():
    """i^2 = j^2 = k^2 = ijk = -1, ij = k, jk = i, ki = j (seed 001 eqs. (2.3)-(2.7))."""
    one, i, j, k = np.eye(4)
    for u in (i, j, k):
        np.testing.assert_array_equal(qmul(u, u), -one)
    np.testing.assert_array_equal(qmul(qmul(i, j), k), -one)
    np.testing.assert_array_equal(qmul(i, j), k)
    np.testing.assert_array_equal(qmul(j, k), i)
    np.testing.assert_array_equal(qmul(k, i), j)
    np.testing.assert_array_equal(qmul(j, i), -k)


@given(quaternions(shape=(3,)), quaternions(shape=(3,)), quaternions(shape=(3,)))
def test_associativity(a, b, c):
    left = qmul(qmul(a, b), c)
    right = qmul(a, qmul(b, c))
    np.testing.assert_allclose(left, right, atol=1e-10 * (1 + np.abs(left).max()))


@given(quaternions())
def test_identity_and_inverse(q):
    np.testing.assert_allclose(qmul(q, IDENTITY), q, atol=0)
    np.testing.assert_allclose(qmul(IDENTITY, q), q, atol=0)
    e = np.broadcast_to(IDENTITY, q.shape)
    np.testing.assert_allclose(qmul(q, qinv(q)), e, atol=1e-12)
    np.testing.assert_allclose(qmul(qinv(q), q), e, atol=1e-12)


@given(same_shape(quaternions, quaternions))
def test_conjugate_and_norm(qp):
    q, p = qp
    # (qp)* = p* q*,  q q* = ||q||^2  (seed 001 eq. (2.19)),  ||qp|| = ||q|| ||p||
    np.testing.assert_allclose(qconj(qmul(q, p)), qmul(qconj(p), qconj(q)), atol=1e-10)
    qq = qmul(q, qconj(q))
    np.testing.assert_allclose(qq[..., 0], qnorm(q) ** 2, rtol=1e-12)
    np.testing.assert_allclose(qq[..., 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(qnorm(qmul(q, p)), qnorm(q) * qnorm(p), rtol=1e-12)


def test_batch_broadcasting():
    q = random_unit_quaternions(12).reshape(3, 4, 4)
    p = random_unit_quaternions(4, seed=1)
    out = qmul(q, p)
    assert out.shape == (3, 4, 4)
    for a in range(3):
        for b in range(4):
            np.testing.assert_allclose(out[a, b], qmul(q[a, b], p[b]), atol=1e-15)


def test_blocked_kernel_matches_loop_across_block_boundary():
    from quatform.algebra import kernels

    n = kernels.BLOCK * 2 + 17
    q, p = random_unit_quaternions(n, 2), random_unit_quaternions(n, 3)
    np.testing.assert_allclose(qmul(q, p), _hamilton_reference(q, p), atol=1e-15)
    np.testing.assert_allclose(qmul(q[:1], p), _hamilton_reference(q[:1], p), atol=1e-15)


@given(quaternions())
def test_exp_log_round_trip(q):
    np.testing.assert_allclose(qexp(qlog(q)), q, atol=1e-10 * (1 + np.abs(q).max()))


@given(unit_quaternions())
@example(np.array([-1.0, 5e-324, 5e-324, 5e-324]))  # a subnormal vector part: the axis still unit
def test_log_of_unit_is_pure_half_angle(q):
    """seed 001 eq. (2.27): ln q = (0, theta/2 n)."""
    lg = qlog(q)
    np.testing.assert_allclose(lg[..., 0], 0.0, atol=1e-12)
    axis, angle = axis_angle_from_q(q)
    np.testing.assert_allclose(lg[..., 1:], 0.5 * angle[..., None] * axis, atol=1e-12)


@given(quaternions(), st.floats(-3, 3), st.floats(-3, 3))
def test_power_adds_exponents(q, a, b):
    lhs = qmul(qpow(q, a), qpow(q, b))
    rhs = qpow(q, a + b)
    np.testing.assert_allclose(lhs, rhs, atol=1e-8 * (1 + np.abs(rhs).max()))


@given(quaternions())
def test_integer_powers(q):
    np.testing.assert_allclose(qpow(q, 2), qmul(q, q), atol=1e-9 * (1 + np.abs(q).max() ** 2))
    np.testing.assert_allclose(qpow(q, -1), qinv(q), atol=1e-9 * (1 + np.abs(qinv(q)).max()))
    np.testing.assert_allclose(qpow(q, 0), np.broadcast_to(IDENTITY, q.shape), atol=1e-12)


@given(same_shape(unit_quaternions, vectors))
def test_rotation_agrees_with_matrix_and_sandwich(qv):
    q, v = qv
    r1 = qrotate(q, v)
    r2 = np.einsum("...ij,...j->...i", matrix_from_q(q), v)
    vq = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1)
    r3 = qmul(qmul(q, vq), qconj(q))[..., 1:]
    np.testing.assert_allclose(r1, r2, atol=1e-10)
    np.testing.assert_allclose(r1, r3, atol=1e-10)


@given(unit_quaternions())
def test_matrix_is_rotation_and_round_trips(q):
    R = matrix_from_q(q)
    np.testing.assert_allclose(np.swapaxes(R, -1, -2) @ R, np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    back = q_from_matrix(R)
    # same rotation, canonical sign
    np.testing.assert_allclose(np.abs(np.sum(back * q, axis=-1)), 1.0, atol=1e-10)
    assert np.all((back[..., 0] > 0) | ((back[..., 0] == 0) & (back[..., 1:] != 0).any(axis=-1)))


def test_q_from_matrix_all_shepperd_branches():
    # angles near pi about each axis force the x, y, z branches; small angle the w branch
    for axis in np.eye(3):
        for angle in (0.1, np.pi - 1e-3, np.pi):
            q = q_from_axis_angle(axis, angle)
            back = q_from_matrix(matrix_from_q(q))
            np.testing.assert_allclose(np.abs(back @ q), 1.0, atol=1e-12)


@given(unit_quaternions())
def test_axis_angle_round_trip_keeps_sign(q):
    axis, angle = axis_angle_from_q(q)
    assert np.all((angle >= 0) & (angle <= 2 * np.pi))
    np.testing.assert_allclose(q_from_axis_angle(axis, angle), q, atol=1e-10)
    axis_s, angle_s = axis_angle_from_q(q, shortest=True)
    assert np.all(angle_s <= np.pi + 1e-12)
    np.testing.assert_allclose(angle_s, q_angle(q), atol=1e-10)


def test_rotation_direction_right_hand_rule():
    q = q_from_axis_angle([0, 0, 1], np.pi / 2)
    np.testing.assert_allclose(qrotate(q, [1, 0, 0]), [0, 1, 0], atol=1e-15)


@given(unit_quaternions(shape=(5,)), unit_quaternions(shape=(5,)), st.floats(0, 1))
def test_slerp_endpoints_and_constant_speed(q0, q1, t):
    np.testing.assert_allclose(np.abs(np.sum(qslerp(q0, q1, 0.0) * q0, -1)), 1.0, atol=1e-10)
    np.testing.assert_allclose(np.abs(np.sum(qslerp(q0, q1, 1.0) * q1, -1)), 1.0, atol=1e-10)
    total = q_angle_between(q0, q1)
    np.testing.assert_allclose(q_angle_between(q0, qslerp(q0, q1, t)), t * total, atol=1e-8)


def test_normalize_and_zero():
    np.testing.assert_allclose(qnormalize([0, 3, 0, 4]), [0, 0.6, 0, 0.8])
    assert qnorm(np.zeros((2, 3, 4))).shape == (2, 3)
    with pytest.raises(ValueError, match="zero quaternion"):
        qnormalize([[1, 0, 0, 0], [0, 0, 0, 0]])


def test_incompatible_batches_raise_shape_error():
    from quatform.errors import ShapeError

    with pytest.raises(ShapeError, match="do not broadcast"):
        qmul(np.ones((2, 4)), np.ones((3, 4)))


def test_log_of_a_subnormal_vector_part_has_a_unit_axis():
    """q = (-1, 0, 5e-324, 5e-324): the vector's norm rounds to 5e-324, and v / |v| was
    (0, 1, 1), not unit, so qpow(q, 2) came out as (-0.86, 0, 0.36, 0.36) (hypothesis found it)."""
    from quatform.algebra import qexp, qlog

    q = np.array([-1.0, 0.0, 5e-324, 5e-324])
    v = qlog(q)[1:]
    assert abs(np.linalg.norm(v) - np.pi) < 1e-12
    np.testing.assert_allclose(qexp(qlog(q)), q, atol=1e-12)
    np.testing.assert_allclose(qpow(q, 2), qmul(q, q), atol=1e-12)
