"""Behaviour at and near every point where an algebra formula divides by zero, takes an
undefined angle, or meets q versus -q.

The points, found by reading each formula:

* ``qlog`` / ``axis_angle_from_q``: ``|v| = 0`` (angle 0 with ``w > 0``; angle 2 pi, ``q = -1``);
* ``qexp`` / ``dqexp``: ``|v| = 0`` (sinc and ``c(a)`` limits) and the series switch of ``c(a)``;
* ``dqlog``: rotation angle 0 (``a = 0``) and ``r = -1`` (``a / sin a`` unbounded);
* ``qcanonical`` and every ``shortest=True`` path: ``w = 0`` (rotations by pi), ``-0.0``;
* ``q_from_matrix``: the Shepperd branches, rotations by pi;
* ``qslerp`` / square roots between orientations pi apart, and between ``q`` and ``-q``.
"""

from __future__ import annotations

import numpy as np
import pytest

from quatform.algebra import (
    axis_angle_from_q,
    dq_from_pose,
    dqexp,
    dqlog,
    dqmul,
    dqnormalize,
    dqpow,
    dqsqrt_decoupled,
    dqsqrt_screw,
    pose_from_dq,
    q_closest,
    q_continuous,
    q_from_axis_angle,
    qcanonical,
    qexp,
    qlog,
    qmul,
    qpow,
    qslerp,
    relative_euler_parameters,
    w_matrix,
)

EPS = [0.0, 1e-300, 1e-200, 1e-20, 1e-12, 1e-8, 1e-4, 1e-2]


def _q_near(sign, e, axis=(0.6, 0.0, 0.8)):
    """Unit quaternion at angle e from sign*1 (sign=+1: identity, -1: minus identity)."""
    return np.concatenate([[sign * np.cos(e)], np.sin(e) * np.asarray(axis)])


@pytest.mark.parametrize("e", EPS)
def test_qlog_near_identity_is_continuous(e):
    q = _q_near(1.0, e)
    lg = qlog(q)
    assert np.all(np.isfinite(lg))
    np.testing.assert_allclose(lg[1:], e * np.array([0.6, 0.0, 0.8]), atol=1e-15)
    np.testing.assert_allclose(qexp(lg), q, atol=1e-15)


@pytest.mark.parametrize("e", EPS)
def test_qlog_near_minus_one_keeps_sign(e):
    """At and near q = -1 (rotation by 2 pi) the principal log has angle ~pi and exp maps it
    back to q itself: no NaN and no silent flip to +1."""
    q = _q_near(-1.0, e)
    lg = qlog(q)
    assert np.all(np.isfinite(lg))
    np.testing.assert_allclose(np.linalg.norm(lg[1:]), np.pi - e, atol=1e-12)
    np.testing.assert_allclose(qexp(lg), q, atol=1e-12)
    # the short way is the log of -q: angle e about the opposite axis
    np.testing.assert_allclose(qlog(q, shortest=True)[1:], -e * np.array([0.6, 0.0, 0.8]), atol=1e-15)


def test_minus_one_exactly():
    lg = qlog([-1.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(lg, [0.0, np.pi, 0.0, 0.0])
    np.testing.assert_allclose(qexp(lg), [-1, 0, 0, 0], atol=1e-15)
    np.testing.assert_allclose(qpow([-1.0, 0, 0, 0], 0.5), [0, 1, 0, 0], atol=1e-15)  # a square root of -1
    np.testing.assert_array_equal(qpow([-1.0, 0, 0, 0], 0.5, shortest=True), [1, 0, 0, 0])
    axis, angle = axis_angle_from_q([-1.0, 0, 0, 0])
    np.testing.assert_array_equal(axis, [1, 0, 0])
    assert angle == pytest.approx(2 * np.pi)


@pytest.mark.parametrize("e", [0.0, 1e-300, 1e-12, 1e-6])
def test_qexp_near_zero_vector(e):
    v = e * np.array([0.0, 0.6, 0.0, 0.8])
    np.testing.assert_allclose(qexp(v), [np.cos(e), 0.0, 0.0, 0.0] + np.sin(e) * np.array([0, 0.6, 0, 0.8]), atol=1e-16)


@pytest.mark.parametrize("w", [0.0, -0.0, 1e-17, -1e-17])
def test_rotation_by_pi(w):
    """w = 0: the rotation by pi. Everything stays finite; canonical form is deterministic."""
    q = np.array([w, 0.0, np.sqrt(1 - w * w), 0.0])
    axis, angle = axis_angle_from_q(q)
    np.testing.assert_allclose(axis, [0, 1, 0])
    np.testing.assert_allclose(angle, np.pi, atol=1e-15)
    c = qcanonical(q)
    assert c[0] > 0 or (c[0] == 0 and c[2] > 0)
    np.testing.assert_array_equal(qcanonical(-q), c)
    h = qpow(q, 0.5, shortest=True)
    np.testing.assert_allclose(np.abs(qmul(h, h) @ q), 1.0, atol=1e-15)


def test_canonical_tie_break_on_the_equator():
    for q in ([0.0, 0.0, 0.0, -1.0], [-0.0, 0.0, -1.0, 0.0], [0.0, -0.6, 0.8, 0.0]):
        c = qcanonical(q)
        first = c[np.nonzero(c)[0][0]]
        assert first > 0
        np.testing.assert_array_equal(np.abs(c), np.abs(q))


def test_canonical_jumps_but_continuous_and_closest_do_not():
    """A rotation passing through pi: canonical signs jump (no continuous section of the
    double cover exists), q_continuous / q_closest keep the signal continuous."""
    t = np.linspace(0, 2 * np.pi, 201)
    q = q_from_axis_angle([0, 0, 1], t)  # crosses w = 0 at t = pi
    can = qcanonical(q)
    jumps = np.linalg.norm(np.diff(can, axis=0), axis=-1)
    assert jumps.max() > 1.9  # the sign flip
    cont = q_continuous(-can)
    assert np.linalg.norm(np.diff(cont, axis=0), axis=-1).max() < 0.02
    np.testing.assert_allclose(cont[0], -can[0])  # first sample keeps its sign
    np.testing.assert_allclose(q_closest(-q[150], q[149]), q[150])


def test_slerp_between_q_and_minus_q_and_half_turns():
    q = q_from_axis_angle([1, 2, 3], 0.4)
    out = qslerp(q, -q, np.linspace(0, 1, 5))  # same rotation: shortest path stays put
    np.testing.assert_allclose(np.abs(out @ q), 1.0, atol=1e-14)
    p = qmul(q, q_from_axis_angle([0, 0, 1], np.pi))  # pi apart: half-way is defined, finite
    mid = qslerp(q, p, 0.5)
    assert np.all(np.isfinite(mid))
    np.testing.assert_allclose(np.linalg.norm(mid), 1.0, atol=1e-15)


@pytest.mark.parametrize("e", EPS)
def test_dqlog_near_zero_rotation_is_continuous_with_pure_translation(e):
    t = np.array([0.3, -1.2, 2.0])
    dq = dq_from_pose(_q_near(1.0, e), t)
    lg = dqlog(dq)
    assert np.all(np.isfinite(lg))
    np.testing.assert_allclose(lg[5:], 0.5 * t, atol=1e-8 + 3 * e)
    np.testing.assert_allclose(dqexp(lg), dq, atol=1e-14)


@pytest.mark.parametrize("e", [0.0, 1e-300, 1e-54, 1e-12, 1e-9, 1e-7, 1e-6, 1e-3])
@pytest.mark.parametrize("across", [0.0, 1.0])
def test_dqlog_at_and_near_minus_one(e, across):
    """r = -1 is the one point where the screw log's a/sin(a) is unbounded. Exactly there the
    axis is taken along d_v (exact); within sin(a) < 1e-8 r is treated as -1; beyond, the
    round trip loses about 1e-16/sin(a). The short-way log never goes there."""
    axis = np.array([0.6, 0.0, 0.8])
    d_tail = 0.5 * axis + across * np.array([0.8, 0.0, -0.6])  # along and across the axis
    dq = dqnormalize(np.concatenate([_q_near(-1.0, e, axis), [0.0], d_tail]))
    lg = dqlog(dq)
    assert np.all(np.isfinite(lg))
    sin_e = np.sin(e)
    bound = max(1e-14, 2 * sin_e if sin_e < 1e-8 else 1e-15 / sin_e)
    np.testing.assert_allclose(dqexp(lg), dq, atol=bound)
    short = dqlog(dq, shortest=True)
    assert np.abs(short).max() < 1.0 + np.linalg.norm(d_tail)  # bounded: no 1/sin(a) gain
    np.testing.assert_allclose(dqexp(short), -dq, atol=1e-14)


@pytest.mark.parametrize("a", [0.0, 1e-8, 9.99e-3, 1e-2, 1.001e-2, 0.5, np.pi - 1e-6, np.pi])
def test_dqexp_series_switch_and_limits(a):
    """c(a) switches from its series to the closed form at a = 1e-2: both sides agree."""
    h = np.zeros(8)
    h[1:4] = a * np.array([0.0, 0.6, 0.8])
    h[5:8] = [0.4, -0.1, 0.3]
    out = dqexp(h)
    assert np.all(np.isfinite(out))
    # compare against central finite difference of the quaternion exp (dual part = derivative)
    k = 1e-6
    fd = (qexp(np.r_[0.0, h[1:4] + k * h[5:8]]) - qexp(np.r_[0.0, h[1:4] - k * h[5:8]])) / (2 * k)
    np.testing.assert_allclose(out[4:], fd, atol=1e-9)


@pytest.mark.parametrize("angle", [0.0, 1e-9, np.pi / 2, np.pi - 1e-9, np.pi, np.pi + 1e-9, 2 * np.pi - 1e-9, 2 * np.pi])
def test_square_roots_through_every_angle(angle):
    dq = dq_from_pose(q_from_axis_angle([0.0, 0.6, 0.8], angle), [1.0, 2.0, -0.5])
    for root in (dqsqrt_decoupled, dqsqrt_screw):
        h = root(dq)
        assert np.all(np.isfinite(h))
        q, _ = pose_from_dq(h)
        assert q[0] >= np.cos(np.pi / 4) - 1e-12  # short way: half-angle at most pi/2
    np.testing.assert_allclose(pose_from_dq(dqsqrt_decoupled(dq))[1], [0.5, 1.0, -0.25], atol=1e-12)
    h = dqsqrt_screw(dq)
    sq = dqmul(h, h)
    np.testing.assert_allclose(np.abs(sq[:4] @ dq[:4]), 1.0, atol=1e-12)
    np.testing.assert_allclose(sq * np.sign(sq[:4] @ dq[:4]), dq, atol=1e-9)


def test_sqrt_same_for_dq_and_minus_dq():
    dq = dq_from_pose(q_from_axis_angle([1, 1, 0], 2.5), [0.1, 0.2, 0.3])
    for root in (dqsqrt_decoupled, dqsqrt_screw):
        np.testing.assert_allclose(root(dq), root(-dq), atol=1e-14)
    assert not np.allclose(dqpow(dq, 0.5), dqpow(-dq, 0.5))  # the principal power keeps the sign


def test_euler_parameter_error_has_no_singular_point():
    """Eqs. (9), (10), (19): polynomial in the parameters, finite at every relative angle,
    including q_S = -q_M (same orientation) and relative rotations by pi."""
    qm = q_from_axis_angle([1, 0, 0], 0.3)
    for qs in (qm, -qm, qmul(qm, q_from_axis_angle([0, 1, 0], np.pi)), qmul(qm, q_from_axis_angle([0, 1, 0], 2 * np.pi))):
        d = relative_euler_parameters(qm, qs)
        W = w_matrix(qm, qs)
        assert np.all(np.isfinite(d)) and np.all(np.isfinite(W))
    np.testing.assert_allclose(relative_euler_parameters(qm, -qm), [-1, 0, 0, 0], atol=1e-15)


@pytest.mark.parametrize("e", [1e-150, 1e-160, 1e-200, 1e-310])
def test_tiny_rotations_do_not_lose_accuracy_to_underflow(e):
    """|v|^2 is subnormal below ~1e-154: the log maps must not divide by an inaccurate |v|
    (hypothesis found dqlog off by 1.3e-4 at |r_v| = 5.8e-161 before norms used hypot)."""
    dq = np.array([1.0, e, 0.0, 0.0, -0.5 * e, 0.5, 0.5, 0.5])
    np.testing.assert_allclose(dqlog(dq)[5:], [0.5, 0.5, 0.5], rtol=1e-15)
    np.testing.assert_allclose(dqexp(dqlog(dq)), dq, rtol=1e-15, atol=1e-300)
    q = np.array([1.0, e, e, 0.0])
    np.testing.assert_allclose(qlog(q)[1:], [e, e, 0.0], rtol=1e-15)
    axis, angle = axis_angle_from_q(q)
    np.testing.assert_allclose(np.linalg.norm(axis), 1.0, rtol=1e-12)  # 1e-310 is itself subnormal
