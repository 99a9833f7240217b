"""Cross-checks against independent libraries used only as test oracles.

pytransform3d (BSD) and dqrobotics (LGPL) are test dependencies; nothing of them is copied
or imported by quatform. Conventions differ (see docs/conventions.md); each test says which
of their functions corresponds to which of ours.
"""

from __future__ import annotations

import numpy as np
import pytest

import quatform.algebra as A

pr = pytest.importorskip("pytransform3d.rotations")
pbr = pytest.importorskip("pytransform3d.batch_rotations")
pt = pytest.importorskip("pytransform3d.transformations")
ptr = pytest.importorskip("pytransform3d.trajectories")
dqr = pytest.importorskip("dqrobotics")

N = 200


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(2024)
    q1 = A.qnormalize(rng.normal(size=(N, 4)))
    q2 = A.qnormalize(rng.normal(size=(N, 4)))
    t1 = rng.uniform(-3, 3, size=(N, 3))
    t2 = rng.uniform(-3, 3, size=(N, 3))
    return q1, q2, t1, t2, A.dq_from_pose(q1, t1), A.dq_from_pose(q2, t2), rng.uniform(-1.5, 1.5, N)


# --- pytransform3d ---------------------------------------------------------------------

def test_pt3d_quaternion_product_conjugate_matrix(data):
    q1, q2, *_ = data
    np.testing.assert_allclose(A.qmul(q1, q2), pbr.batch_concatenate_quaternions(q1, q2), atol=1e-14)
    np.testing.assert_allclose(A.qconj(q1), pbr.batch_q_conj(q1), atol=0)
    np.testing.assert_allclose(A.matrix_from_q(q1), pbr.matrices_from_quaternions(q1), atol=1e-14)
    back = pbr.quaternions_from_matrices(A.matrix_from_q(q1))
    np.testing.assert_allclose(A.q_from_matrix(A.matrix_from_q(q1)), A.qcanonical(back), atol=1e-12)


def test_pt3d_axis_angle_and_power(data):
    q1, _, _, _, _, _, a = data
    for q, ai in zip(q1[:50], a[:50]):
        axis, angle = A.axis_angle_from_q(q, shortest=True)
        ref = pr.axis_angle_from_quaternion(q)  # angle in [0, pi], sign of q dropped
        np.testing.assert_allclose(angle, ref[3], atol=1e-12)
        np.testing.assert_allclose(axis, ref[:3], atol=1e-10)
        # quaternion_slerp(I, q, t) is the principal power q^t, sign kept
        np.testing.assert_allclose(A.qpow(q, ai), pr.quaternion_slerp(A.IDENTITY, q, ai), atol=1e-10)
        np.testing.assert_allclose(
            A.qexp(A.qlog(q, shortest=True)) * 2, pr.quaternion_from_compact_axis_angle(pr.compact_axis_angle_from_quaternion(q)) * 2, atol=1e-10
        )


def test_pt3d_dual_quaternion_product_conjugates_pose(data):
    _, _, t1, _, d1, d2, _ = data
    np.testing.assert_allclose(A.dqmul(d1, d2), ptr.batch_concatenate_dual_quaternions(d1, d2), atol=1e-13)
    np.testing.assert_allclose(A.dqconj(d1), ptr.batch_dq_q_conj(d1), atol=0)
    np.testing.assert_allclose(A.dqconj_combined(d1), ptr.batch_dq_conj(d1), atol=0)
    q, t = A.pose_from_dq(d1)
    pqs = ptr.pqs_from_dual_quaternions(d1)  # (x, y, z, qw, qx, qy, qz)
    np.testing.assert_allclose(t, pqs[:, :3], atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(q * pqs[:, 3:], -1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(A.dq_from_pose(pqs[:, 3:], pqs[:, :3]) * np.sign(np.sum(q * pqs[:, 3:], -1))[:, None], d1, atol=1e-12)
    np.testing.assert_allclose(A.dq_transform_point(d1, t1), ptr.batch_dq_prod_vector(d1, t1), atol=1e-12)


def test_pt3d_screw_power_and_sclerp(data):
    """pytransform3d's dual_quaternions_power is the screw power, taken the short way."""
    _, _, _, _, d1, d2, a = data
    ref = ptr.dual_quaternions_power(d1, a)
    ours = A.dqpow(d1, a, shortest=True)
    np.testing.assert_allclose(A.dq_closest(ours, ref), ref, atol=1e-9)
    ours_half = A.dqsqrt_screw(d1)
    ref_half = ptr.dual_quaternions_power(d1, np.full(N, 0.5))
    np.testing.assert_allclose(A.dq_closest(ours_half, ref_half), ref_half, atol=1e-9)
    t = np.linspace(0, 1, N)
    ref_s = ptr.dual_quaternions_sclerp(d1, d2, t)
    ours_s = A.dqmul(d1, A.dqpow(A.dqmul(A.dqconj(d1), d2), t, shortest=True))
    np.testing.assert_allclose(A.dq_closest(ours_s, ref_s), ref_s, atol=1e-9)


def test_pt3d_screw_log_matches_screw_parameters(data):
    """dqlog = 1/2 (theta s + eps (h theta s + theta (q x s))) for screw (q, s, h, theta)."""
    _, _, _, _, d1, _, _ = data
    for dq in d1[:40]:
        qp, s, h, theta = pt.screw_parameters_from_dual_quaternion(dq)
        lg = A.dqlog(dq, shortest=True)
        np.testing.assert_allclose(lg[1:4], 0.5 * theta * s, atol=1e-10)
        np.testing.assert_allclose(lg[5:8], 0.5 * (h * theta * s + theta * np.cross(qp, s)), atol=1e-9)


# --- dqrobotics ------------------------------------------------------------------------

def _DQ(x):
    return dqr.DQ(np.asarray(x, dtype=float))


def test_dqrobotics_product_conjugates_norm_inverse(data):
    _, _, _, _, d1, d2, _ = data
    raw = np.random.default_rng(5).normal(size=(20, 8))
    for a, b, r in zip(d1[:50], d2[:50], raw):
        np.testing.assert_allclose(A.dqmul(a, b), (_DQ(a) * _DQ(b)).vec8(), atol=1e-13)
        np.testing.assert_allclose(A.dqconj(a), dqr.conj(_DQ(a)).vec8(), atol=0)
        np.testing.assert_allclose(A.dqconj_dual(a), dqr.sharp(_DQ(a)).vec8(), atol=0)
        np.testing.assert_allclose(A.dqinv(r), dqr.inv(_DQ(r)).vec8(), atol=1e-10)
        n = dqr.norm(_DQ(r)).vec8()
        np.testing.assert_allclose(A.dqnorm(r), [n[0], n[4]], atol=1e-12)
        np.testing.assert_allclose(A.dqnormalize(r), dqr.normalize(_DQ(r)).vec8(), atol=1e-12)


def test_dqrobotics_pose_translation_rotation(data):
    q1, _, t1, _, d1, _, _ = data
    for q, t, dq in zip(q1[:50], t1[:50], d1[:50]):
        X = _DQ(dq)
        np.testing.assert_allclose(A.pose_from_dq(dq)[1], dqr.translation(X).vec3(), atol=1e-12)
        np.testing.assert_allclose(A.pose_from_dq(dq)[0], dqr.rotation(X).vec4(), atol=1e-12)
        ref = dqr.DQ(q) + dqr.E_ * 0.5 * dqr.DQ(t) * dqr.DQ(q)
        np.testing.assert_allclose(A.dq_from_pose(q, t), ref.vec8(), atol=1e-12)
        axis, angle = A.axis_angle_from_q(q)  # both keep the sign: angle in [0, 2 pi]
        np.testing.assert_allclose(angle, dqr.rotation_angle(X), atol=1e-7)


def test_dqrobotics_log_exp_pow_are_the_decoupled_ones(data):
    """dqrobotics log/exp/pow keep the sign and treat rotation and translation separately."""
    _, _, _, _, d1, _, a = data
    for dq, ai in zip(d1[:80], a[:80]):
        if dq[0] < -0.99:  # dqrobotics loses precision within ~1e-3 of r = -1 (see notes)
            continue
        X = _DQ(dq)
        np.testing.assert_allclose(A.dqlog_decoupled(dq), dqr.log(X).vec8(), atol=1e-10)
        np.testing.assert_allclose(A.dqexp_decoupled(A.dqlog_decoupled(dq)), dqr.exp(dqr.log(X)).vec8(), atol=1e-10)
        np.testing.assert_allclose(A.dqpow_decoupled(dq, ai), dqr.pow(X, float(ai)).vec8(), atol=1e-9)
        np.testing.assert_allclose(A.dqsqrt_decoupled(dq, shortest=False), X.pow(0.5).vec8(), atol=1e-9)
    # pure rotations: both logs coincide with the quaternion log
    for q in data[0][:20]:
        np.testing.assert_allclose(A.dqlog(np.r_[q, np.zeros(4)])[1:4], dqr.log(_DQ(q)).vec4()[1:], atol=1e-10)


def test_dqrobotics_hamilton_operators(data):
    _, _, _, _, d1, d2, _ = data
    for a in d1[:20]:
        np.testing.assert_allclose(A.dqplus(a), dqr.hamiplus8(_DQ(a)), atol=1e-14)
        np.testing.assert_allclose(A.dqminus(a), dqr.haminus8(_DQ(a)), atol=1e-14)
        np.testing.assert_allclose(A.qplus(a[:4]), dqr.hamiplus4(_DQ(a[:4])), atol=1e-14)
        np.testing.assert_allclose(A.qminus(a[:4]), dqr.haminus4(_DQ(a[:4])), atol=1e-14)
