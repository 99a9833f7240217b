"""Jacobian matrices of seed 001 §2.2.7 and the rate/integration functions, against finite
differences and closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given

from quatform.algebra import (
    CONJ,
    INTEGRATORS,
    angular_acceleration_from_qddot,
    angular_velocity_from_qdot,
    dqminus,
    dqmul,
    dqplus,
    integrate,
    jac_qrotate_quaternion,
    jac_qrotate_vector,
    matrix_from_q,
    q_angle_between,
    q_from_axis_angle,
    qconj,
    qddot_from_angular_acceleration,
    qdot_from_angular_velocity,
    qdot_matrix,
    qminus,
    qmul,
    qplus,
    skew,
)

from conftest import numeric_jacobian, quaternions, same_shape, unit_dual_quaternions, vectors


def _pure(v):
    return np.concatenate([[0.0], v])


@given(same_shape(quaternions, quaternions))
def test_plus_minus_are_product_matrices(qp):
    q, p = qp
    np.testing.assert_allclose(np.einsum("...ij,...j->...i", qplus(q), p), qmul(q, p), atol=1e-12)
    np.testing.assert_allclose(np.einsum("...ij,...j->...i", qminus(p), q), qmul(q, p), atol=1e-12)


@given(same_shape(unit_dual_quaternions, unit_dual_quaternions))
def test_dual_plus_minus_are_product_matrices(ab):
    a, b = ab
    np.testing.assert_allclose(np.einsum("...ij,...j->...i", dqplus(a), b), dqmul(a, b), atol=1e-12)
    np.testing.assert_allclose(np.einsum("...ij,...j->...i", dqminus(b), a), dqmul(a, b), atol=1e-12)


@given(vectors(), vectors())
def test_skew_is_cross(a, b):
    try:
        np.broadcast_shapes(a.shape, b.shape)
    except ValueError:
        b = b.reshape(-1, 3)[0]
    np.testing.assert_allclose(np.einsum("...ij,...j->...i", skew(a), b), np.cross(a, b), atol=1e-12)


def test_seed001_product_partials_2_40_to_2_43():
    rng = np.random.default_rng(11)
    for _ in range(10):
        q, p = rng.normal(size=4), rng.normal(size=4)
        # (2.40) d(q p)/dq, (2.41) d(q p*)/dq, (2.42) d(q p)/dp, (2.43) d(q p*)/dp
        np.testing.assert_allclose(numeric_jacobian(lambda x: qmul(x, p), q), qminus(p), atol=1e-8)
        np.testing.assert_allclose(numeric_jacobian(lambda x: qmul(x, qconj(p)), q), qminus(qconj(p)), atol=1e-8)
        np.testing.assert_allclose(numeric_jacobian(lambda x: qmul(q, x), p), qplus(q), atol=1e-8)
        np.testing.assert_allclose(numeric_jacobian(lambda x: qmul(q, qconj(x)), p), qplus(q) @ CONJ, atol=1e-8)
        # printed forms of (2.41) and (2.43), entry by entry
        p0, pv = p[0], p[1:]
        printed_241 = np.block([[p0, pv[None, :]], [-pv[:, None], p0 * np.eye(3) + skew(pv)]])
        np.testing.assert_allclose(qminus(qconj(p)), printed_241, atol=1e-14)
        q0, qv = q[0], q[1:]
        printed_243 = np.block([[q0, qv[None, :]], [qv[:, None], -q0 * np.eye(3) - skew(qv)]])
        np.testing.assert_allclose(qplus(q) @ CONJ, printed_243, atol=1e-14)


def test_seed001_rotation_partials_2_45_to_2_47():
    rng = np.random.default_rng(12)
    for _ in range(10):
        q, v = rng.normal(size=4), rng.normal(size=3)

        def rot(qq, vv):
            return qmul(qmul(qq, _pure(vv)), qconj(qq))[1:]

        np.testing.assert_allclose(numeric_jacobian(lambda x: rot(q, x), v), jac_qrotate_vector(q), atol=1e-8)
        np.testing.assert_allclose(
            numeric_jacobian(lambda x: rot(qconj(q), x), v), jac_qrotate_vector(qconj(q)), atol=1e-8
        )
        np.testing.assert_allclose(numeric_jacobian(lambda x: rot(x, v), q), jac_qrotate_quaternion(q, v), atol=1e-7)
    qu = q / np.linalg.norm(q)
    np.testing.assert_allclose(jac_qrotate_vector(qu), matrix_from_q(qu), atol=1e-14)


@pytest.mark.parametrize("frame", ["world", "body"])
def test_qdot_matrix_and_angular_velocity_round_trip(frame):
    rng = np.random.default_rng(13)
    q = rng.normal(size=(20, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    w = rng.normal(size=(20, 3))
    qd = qdot_from_angular_velocity(q, w, frame)
    np.testing.assert_allclose(np.einsum("...ij,...j->...i", qdot_matrix(q, frame), w), qd, atol=1e-14)
    np.testing.assert_allclose(np.sum(q * qd, -1), 0.0, atol=1e-14)  # tangent to the sphere
    np.testing.assert_allclose(angular_velocity_from_qdot(q, qd, frame), w, atol=1e-12)


def test_world_angular_velocity_is_what_rotates_vectors():
    """seed 001 eq. (2.32): with q_dot = 1/2 w q, d/dt (R(q) v) = w x R(q) v."""
    q = q_from_axis_angle([1, 2, 3], 0.7)
    w = np.array([0.3, -0.2, 0.5])
    v = np.array([0.4, 1.0, -2.0])
    h = 1e-6
    qd = qdot_from_angular_velocity(q, w)
    dRv = (matrix_from_q((q + h * qd) / np.linalg.norm(q + h * qd)) @ v - matrix_from_q((q - h * qd) / np.linalg.norm(q - h * qd)) @ v) / (2 * h)
    np.testing.assert_allclose(dRv, np.cross(w, matrix_from_q(q) @ v), atol=1e-8)


@pytest.mark.parametrize("frame", ["world", "body"])
def test_second_derivative_and_angular_acceleration(frame):
    """seed 001 eqs. (2.34)-(2.35) against finite differences of a smooth motion."""
    w0, w1 = np.array([0.3, -0.4, 0.2]), np.array([0.1, 0.2, -0.3])

    def omega(t):
        return w0 + w1 * t

    def q_of(t, n=4000):
        q = q_from_axis_angle([1, 0, 0], 0.0)
        dt = t / n
        for k in range(n):
            q = integrate(q, omega((k + 0.5) * dt), dt, frame=frame)
        return q

    t, h = 0.8, 1e-3
    qm, q0, qp = q_of(t - h), q_of(t), q_of(t + h)
    qd = (qp - qm) / (2 * h)
    qdd = (qp - 2 * q0 + qm) / h**2
    np.testing.assert_allclose(qd, qdot_from_angular_velocity(q0, omega(t), frame), atol=1e-6)
    np.testing.assert_allclose(qdd, qddot_from_angular_acceleration(q0, omega(t), w1, frame), atol=1e-5)
    exact_qd = qdot_from_angular_velocity(q0, omega(t), frame)
    exact_qdd = qddot_from_angular_acceleration(q0, omega(t), w1, frame)
    np.testing.assert_allclose(angular_acceleration_from_qddot(q0, exact_qd, exact_qdd, frame), w1, atol=1e-12)


def test_integrators_constant_rate():
    w = np.array([0.3, -0.5, 0.8])
    dt, n = 0.01, 2000
    exact = q_from_axis_angle(w, np.linalg.norm(w) * n * dt)
    errs = {}
    for method in INTEGRATORS:
        q = np.array([1.0, 0, 0, 0])
        for _ in range(n):
            q = integrate(q, w, dt, method=method)
        nq = np.linalg.norm(q)
        errs[method] = (nq - 1.0, float(q_angle_between(q / nq, exact)))
    assert abs(errs["exp"][0]) < 1e-12 and errs["exp"][1] < 1e-11  # exact for constant w
    for m in ("euler-normalized", "euler-log"):
        assert abs(errs[m][0]) < 1e-12
        assert 1e-6 < errs[m][1] < 1e-2  # first-order phase error
    grow = (1 + dt**2 * np.dot(w, w) / 4) ** (n / 2) - 1  # explicit Euler: norm grows
    np.testing.assert_allclose(errs["euler"][0], grow, rtol=1e-6)


def test_integrate_batches_and_rejects_unknown_method():
    q = np.tile([1.0, 0, 0, 0], (5, 1))
    w = np.random.default_rng(0).normal(size=(5, 3))
    out = integrate(q, w, np.linspace(0.01, 0.05, 5))
    assert out.shape == (5, 4)
    with pytest.raises(ValueError, match="method must be one of"):
        integrate(q, w, 0.1, method="rk4")
    with pytest.raises(ValueError, match="frame must be"):
        integrate(q, w, 0.1, frame="inertial")
