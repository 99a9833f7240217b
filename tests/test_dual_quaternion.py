"""Dual-quaternion algebra: products, poses, log/exp, the screw and decoupled powers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, strategies as st

from quatform.algebra import (
    DQ_IDENTITY,
    dq_closest,
    dq_from_pose,
    dq_transform_point,
    dqcanonical,
    dqconj,
    dqconj_combined,
    dqconj_dual,
    dqexp,
    dqexp_decoupled,
    dqinv,
    dqlog,
    dqlog_decoupled,
    dqmul,
    dqnorm,
    dqnormalize,
    dqpow,
    dqpow_decoupled,
    dqsqrt_decoupled,
    dqsqrt_screw,
    matrix_from_q,
    pose_from_dq,
    q_angle_between,
    q_from_axis_angle,
    qmul,
    qpow,
)

from conftest import same_shape, unit_dual_quaternions, unit_quaternions, vectors


def _dq_reference(a, b):
    ra, da, rb, db = a[..., :4], a[..., 4:], b[..., :4], b[..., 4:]
    return np.concatenate([qmul(ra, rb), qmul(ra, db) + qmul(da, rb)], axis=-1)


@given(same_shape(unit_dual_quaternions, unit_dual_quaternions))
def test_product_is_dual_number_product(ab):
    a, b = ab
    np.testing.assert_allclose(dqmul(a, b), _dq_reference(a, b), atol=1e-12)


@given(same_shape(unit_dual_quaternions, unit_dual_quaternions, unit_dual_quaternions))
def test_associativity_and_inverse(abc):
    a, b, c = abc
    np.testing.assert_allclose(dqmul(dqmul(a, b), c), dqmul(a, dqmul(b, c)), atol=1e-9)
    e = np.broadcast_to(DQ_IDENTITY, a.shape)
    np.testing.assert_allclose(dqmul(a, dqconj(a)), e, atol=1e-10)
    np.testing.assert_allclose(dqmul(dqinv(a), a), e, atol=1e-10)


@given(same_shape(unit_quaternions, vectors, unit_quaternions, vectors))
def test_product_composes_poses(x):
    q1, t1, q2, t2 = x
    """T1 T2: rotation q1 q2, translation t1 + R1 t2."""
    q, t = pose_from_dq(dqmul(dq_from_pose(q1, t1), dq_from_pose(q2, t2)))
    np.testing.assert_allclose(np.abs(np.sum(q * qmul(q1, q2), -1)), 1.0, atol=1e-10)
    np.testing.assert_allclose(t, t1 + np.einsum("...ij,...j->...i", matrix_from_q(q1), t2), atol=1e-9)


@given(same_shape(unit_quaternions, vectors))
def test_pose_round_trip(x):
    q, t = x
    dq = dq_from_pose(q, t)
    q2, t2 = pose_from_dq(dq)
    np.testing.assert_allclose(q2, q, atol=1e-12)
    np.testing.assert_allclose(t2, t, atol=1e-12)
    np.testing.assert_allclose(dqnorm(dq), np.broadcast_to([1.0, 0.0], q.shape[:-1] + (2,)), atol=1e-12)


@given(same_shape(unit_dual_quaternions, vectors))
def test_transform_point_matches_sandwich(x):
    dq, p = x
    pure = np.zeros(p.shape[:-1] + (8,))
    pure[..., 0] = 1.0
    pure[..., 5:] = p
    sandwich = dqmul(dqmul(dq, pure), dqconj_combined(dq))
    np.testing.assert_allclose(sandwich[..., 5:], dq_transform_point(dq, p), atol=1e-9)


def test_conjugate_sign_patterns():
    x = np.arange(1.0, 9.0)
    np.testing.assert_array_equal(dqconj(x), [1, -2, -3, -4, 5, -6, -7, -8])
    np.testing.assert_array_equal(dqconj_dual(x), [1, 2, 3, 4, -5, -6, -7, -8])
    np.testing.assert_array_equal(dqconj_combined(x), [1, -2, -3, -4, -5, 6, 7, 8])


def test_norm_normalize_inverse_of_general_dq():
    rng = np.random.default_rng(4)
    x = rng.normal(size=(6, 8))
    n = dqnormalize(x)
    np.testing.assert_allclose(np.linalg.norm(n[:, :4], axis=-1), 1.0, atol=1e-14)
    np.testing.assert_allclose(np.sum(n[:, :4] * n[:, 4:], -1), 0.0, atol=1e-14)
    # x = ||x|| * normalize(x) as dual numbers: (a + eps b)(r' + eps d') = a r' + eps (a d' + b r')
    nn = dqnorm(x)
    rebuilt = np.concatenate([nn[:, :1] * n[:, :4], nn[:, :1] * n[:, 4:] + nn[:, 1:] * n[:, :4]], axis=-1)
    np.testing.assert_allclose(rebuilt, x, atol=1e-12)
    np.testing.assert_allclose(dqmul(x, dqinv(x)), np.broadcast_to(DQ_IDENTITY, x.shape), atol=1e-12)


@given(unit_dual_quaternions())
def test_exp_log_round_trip(dq):
    """Everywhere for the short-way log; for the principal log away from r = -1 (its
    behaviour at and near that point is in test_singular_points)."""
    short = dqlog(dq, shortest=True)
    np.testing.assert_allclose(short[..., [0, 4]], 0.0, atol=0)
    np.testing.assert_allclose(dqexp(short), dqcanonical(dq), atol=1e-9)
    assume(np.all(dq[..., 0] > -0.99))
    np.testing.assert_allclose(dqexp(dqlog(dq)), dq, atol=1e-9)


@given(unit_dual_quaternions(), st.floats(-2, 2), st.floats(-2, 2))
def test_screw_power_adds_exponents(dq, a, b):
    """Holds everywhere for the short-way power; for the principal (sign-keeping) power away
    from r = -1, where its log is ill-conditioned (see test_singular_points)."""
    np.testing.assert_allclose(
        dqmul(dqpow(dq, a, shortest=True), dqpow(dq, b, shortest=True)), dqpow(dq, a + b, shortest=True), atol=1e-8
    )
    assume(np.all(dq[..., 0] > -0.99))
    np.testing.assert_allclose(dqmul(dqpow(dq, a), dqpow(dq, b)), dqpow(dq, a + b), atol=1e-8)


@given(unit_dual_quaternions())
def test_screw_power_integer_and_root(dq):
    np.testing.assert_allclose(dqpow(dq, 2, shortest=True), dqmul(dq, dq), atol=1e-9)
    assume(np.all(dq[..., 0] > -0.99))
    np.testing.assert_allclose(dqpow(dq, 2), dqmul(dq, dq), atol=1e-9)
    np.testing.assert_allclose(dqpow(dq, -1), dqconj(dq), atol=1e-9)
    h = dqsqrt_screw(dq, shortest=False)
    np.testing.assert_allclose(dqmul(h, h), dq, atol=1e-9)
    hs = dqsqrt_screw(dq)  # shortest: square is +-dq
    sq = dqmul(hs, hs)
    np.testing.assert_allclose(np.abs(np.sum(sq * dq, -1)), np.sum(dq * dq, -1), atol=1e-8)


def _series_exp(h, terms=40):
    """Truncated power series sum h^n / n! of a dual quaternion."""
    term = DQ_IDENTITY.copy()
    total = term.copy()
    for n in range(1, terms):
        term = dqmul(term, h) / n
        total += term
    return total


def test_exp_of_pure_dual_quaternion_is_the_series():
    rng = np.random.default_rng(7)
    for _ in range(5):
        h = np.zeros(8)
        h[1:4] = rng.normal(size=3)
        h[5:8] = rng.normal(size=3)
        np.testing.assert_allclose(dqexp(h), _series_exp(h), atol=1e-12)


def test_exp_with_scalar_parts():
    h = np.array([0.3, 0.2, -0.1, 0.4, 0.5, 0.1, 0.2, 0.3])
    np.testing.assert_allclose(dqexp(h), _series_exp(h), atol=1e-12)


@given(same_shape(unit_quaternions, vectors), st.floats(-2, 2))
def test_decoupled_power_scales_translation(x, a):
    q, t = x
    dq = dq_from_pose(q, t)
    qa, ta = pose_from_dq(dqpow_decoupled(dq, a))
    np.testing.assert_allclose(ta, a * t, atol=1e-9)
    np.testing.assert_allclose(qa, qpow(q, a), atol=1e-9)
    np.testing.assert_allclose(dqexp_decoupled(dqlog_decoupled(dq)), dq, atol=1e-9)


def test_screw_root_is_not_the_midpoint_but_decoupled_is():
    """The two square roots differ exactly when the rotation axis is not along the translation."""
    q = q_from_axis_angle([0, 0, 1], 2.0)
    t = np.array([1.0, 0.5, 0.2])
    dq = dq_from_pose(q, t)
    _, t_screw = pose_from_dq(dqsqrt_screw(dq))
    _, t_dec = pose_from_dq(dqsqrt_decoupled(dq))
    np.testing.assert_allclose(t_dec, t / 2, atol=1e-14)
    assert np.linalg.norm(t_screw - t / 2) > 0.1
    # along the axis they agree
    dq_par = dq_from_pose(q, [0, 0, 0.7])
    np.testing.assert_allclose(dqsqrt_screw(dq_par), dqsqrt_decoupled(dq_par), atol=1e-14)


@given(same_shape(unit_quaternions, vectors, unit_quaternions, vectors))
def test_seed000_eq26_cluster_frame_is_midway(x):
    """seed 000 eqs. (26)-(27) with the decoupled root: cluster at the midpoint, orientation
    half-way between the robots, and the printed inverse kinematics hold."""
    q1, p1, q2, p2 = x
    d1, d2 = dq_from_pose(q1, p1), dq_from_pose(q2, p2)
    qs = dqmul(dqconj(d2), d1)  # eq. (27)
    h = dqsqrt_decoupled(qs)
    qc = dqmul(d2, h)  # eq. (26)
    rc, pc = pose_from_dq(qc)
    np.testing.assert_allclose(pc, 0.5 * (p1 + p2), atol=1e-9)
    a1, a2 = q_angle_between(rc, q1), q_angle_between(rc, q2)
    np.testing.assert_allclose(a1, a2, atol=1e-7)
    np.testing.assert_allclose(a1 + a2, q_angle_between(q1, q2), atol=1e-7)
    # inverse kinematics from the same root h: q2 = qc h*, q1 = qc h* qs (exact everywhere)
    np.testing.assert_allclose(dqmul(qc, dqconj(h)), d2, atol=1e-9)
    np.testing.assert_allclose(dqmul(dqmul(qc, dqconj(h)), qs), d1, atol=1e-9)
    # as printed under eq. (27), q1 = qc ((qs*)^1/2)*: right up to sign, except at a relative
    # half turn, where the short way of qs* = -qs picks the same root as for qs
    printed = dq_closest(dqmul(qc, dqconj(dqsqrt_decoupled(dqconj(qs)))), d1)
    half_turn = np.abs(qs[..., 0]) < 1e-9
    np.testing.assert_allclose(printed[~half_turn], np.asarray(d1)[~half_turn], atol=1e-9)


def test_canonical_and_closest():
    dq = dq_from_pose(q_from_axis_angle([1, 0, 0], 4.0), [1, 2, 3])  # w < 0
    c = dqcanonical(dq)
    assert c[0] > 0
    np.testing.assert_allclose(c, -dq)
    np.testing.assert_allclose(dq_closest(dq, c), c)
    np.testing.assert_allclose(dq_closest(c, dq), dq)


def test_decoupled_exp_rejects_non_pure():
    with pytest.raises(ValueError, match="pure dual quaternion"):
        dqexp_decoupled([1, 0, 0, 0, 0, 0, 0, 0])
