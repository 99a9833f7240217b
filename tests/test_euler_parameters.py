"""Seed 003: Euler parameters, the relative orientation (9)-(10) and the matrix W (19)."""

from __future__ import annotations

import numpy as np
from hypothesis import given

from quatform.algebra import (
    euler_parameters_from_q,
    matrix_from_q,
    q_angle_between,
    q_from_axis_angle,
    q_from_euler_parameters,
    q_from_matrix,
    qconj,
    qdot_from_angular_velocity,
    qdot_matrix,
    qmul,
    relative_euler_parameters,
    w_matrix,
)

from conftest import same_shape, unit_quaternions


def test_definition_eqs_1_to_4():
    k, theta = np.array([0.0, 0.6, 0.8]), 1.1
    eps = euler_parameters_from_q(q_from_axis_angle(k, theta))
    np.testing.assert_allclose(eps, np.r_[k * np.sin(theta / 2), np.cos(theta / 2)], atol=1e-15)
    np.testing.assert_allclose(q_from_euler_parameters(eps), q_from_axis_angle(k, theta), atol=1e-15)


@given(same_shape(unit_quaternions, unit_quaternions))
def test_relative_parameters_are_qm_conj_qs(x):
    qm, qs = x
    d = relative_euler_parameters(qm, qs)
    np.testing.assert_allclose(d, qmul(qconj(qm), qs), atol=1e-12)
    # eq. (8): the matrix of d is R_M^T R_S
    Rm, Rs = matrix_from_q(qm), matrix_from_q(qs)
    np.testing.assert_allclose(matrix_from_q(d), np.swapaxes(Rm, -1, -2) @ Rs, atol=1e-10)


def test_rates_eqs_6_7_are_world_frame():
    """eps4_dot = -1/2 eps^T w, eps_dot = 1/2 (eps4 I - [eps]x) w with w in the base frame {A}."""
    q = q_from_axis_angle([1, -2, 0.5], 0.9)
    w = np.array([0.2, -0.7, 0.4])
    e4, e = q[0], q[1:]
    ex = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    np.testing.assert_allclose(qdot_from_angular_velocity(q, w, "world"), np.r_[-0.5 * e @ w, 0.5 * (e4 * np.eye(3) - ex) @ w], atol=1e-15)
    np.testing.assert_allclose(qdot_matrix(q, "world")[1:], 0.5 * (e4 * np.eye(3) - ex), atol=1e-15)


def test_w_maps_angular_velocity_difference_to_error_rate():
    """Finite differences: d/dt (vector part of q_M* q_S) = W (w_S - w_M), both in the base frame."""
    rng = np.random.default_rng(21)
    h = 1e-6
    for _ in range(20):
        qm, qs = (q / np.linalg.norm(q) for q in rng.normal(size=(2, 4)))
        wm, ws = rng.normal(size=(2, 3))
        W = w_matrix(qm, qs)

        def err(t):
            qm_t = qm + t * qdot_from_angular_velocity(qm, wm)
            qs_t = qs + t * qdot_from_angular_velocity(qs, ws)
            return relative_euler_parameters(qm_t / np.linalg.norm(qm_t), qs_t / np.linalg.norm(qs_t))[1:]

        rate = (err(h) - err(-h)) / (2 * h)
        np.testing.assert_allclose(rate, W @ (ws - wm), atol=1e-8)
        # and W is eq. (19) as printed, term by term
        np.testing.assert_allclose(
            W, 0.5 * (np.outer(qs[1:], qm[1:]) + (qs[0] * np.eye(3) - _skew(qs[1:])) @ (qm[0] * np.eye(3) - _skew(qm[1:])))
        )


def _skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def test_w_singular_values_follow_the_error_angle():
    """W = 1/2 R_M^T (d4 I - [d]x): singular values 1/2, 1/2, |d4|/2 = |cos(theta/2)|/2.

    Aligned (theta = 0) W = R_M^T / 2; only a 180-degree error, where |d_eps| is at its
    maximum, makes W singular."""
    q = q_from_axis_angle([0.3, 0.4, 0.5], 2.0)
    np.testing.assert_allclose(w_matrix(q, q), 0.5 * matrix_from_q(q).T, atol=1e-15)
    rng = np.random.default_rng(3)
    for _ in range(100):
        qm = rng.normal(size=4)
        qm /= np.linalg.norm(qm)
        dq = q_from_axis_angle(rng.normal(size=3), rng.uniform(0, 3.0))  # error below 172 deg
        sv = np.linalg.svd(w_matrix(qm, qmul(qm, dq)), compute_uv=False)
        angle = q_angle_between(qm, qmul(qm, dq))
        np.testing.assert_allclose(sv, [0.5, 0.5, 0.5 * np.cos(angle / 2)], atol=1e-12)
    half_turn = qmul(q, q_from_axis_angle([0, 0, 1], np.pi))
    assert np.linalg.svd(w_matrix(q, half_turn), compute_uv=False).min() < 1e-15


def test_small_and_large_angle_behaviour_of_the_error():
    """|d_eps| = sin(angle/2): ~angle/2 for small errors, saturating at 1 for a half turn."""
    qm = q_from_axis_angle([0, 0, 1], 0.4)
    for angle in (1e-6, 1e-3, 0.1, 1.0, 2.0, np.pi):
        qs = qmul(qm, q_from_axis_angle([1, 1, 0], angle))
        d = relative_euler_parameters(qm, qs)
        np.testing.assert_allclose(np.linalg.norm(d[1:]), np.sin(angle / 2), atol=1e-14)
        np.testing.assert_allclose(q_angle_between(qm, qs), angle, atol=1e-7)
    d = relative_euler_parameters(qm, qmul(qm, q_from_axis_angle([1, 0, 0], 1e-4)))
    np.testing.assert_allclose(np.linalg.norm(d[1:]), 0.5e-4, rtol=1e-8)


def test_matrix_round_trip_used_by_teleoperation():
    q = q_from_axis_angle([1, 2, 3], 2.9)
    np.testing.assert_allclose(np.abs(q_from_matrix(matrix_from_q(q)) @ q), 1.0, atol=1e-14)
