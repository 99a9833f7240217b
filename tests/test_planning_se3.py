"""Seed 004 §2: metrics inherited from GL(3)/GA(3), the projection of Proposition 2.1, and
projected geodesics / minimum-acceleration curves."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.linalg import polar
from scipy.spatial.transform import Rotation

from quatform.algebra import matrix_from_q, q_from_matrix, qslerp, skew
from quatform.errors import DegenerateInputError, InvalidInputError, NotARotationError
from quatform.planning.se3 import (
    ProjectedCurve,
    g_from_w,
    metric_ga,
    metric_gl,
    metric_se3,
    metric_so3,
    project_to_se3,
    project_to_so3,
    projected_rotation_rates,
    twist_matrix,
    vee,
    w_from_g,
)

seeds = st.integers(0, 2**32 - 1)


def _trapezoid(y, x):
    """Trapezoid rule (``numpy.trapezoid`` needs NumPy 2)."""
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))



def random_rotation(rng, n=None):
    return Rotation.random(n, random_state=rng).as_matrix()


def random_spd(rng, rank=3):
    A = rng.normal(size=(3, rank))
    return A @ A.T + (1e-3 * np.eye(3) if rank == 3 else 0.0)


def wdist2(B, R, W):
    """Squared distance ``Tr((B - R)^T (B - R) W)`` of metric (5)."""
    D = B - R
    return np.einsum("...ki,...kj,ji->...", D, D, W)


# --------------------------------------------------------------------------- metrics


@given(seeds)
def test_g_w_are_inverse_and_so3_metric_is_the_restriction(seed):
    """eq. (7) both ways, and eq. (6) = eq. (5) on T_R SO(3)."""
    rng = np.random.default_rng(seed)
    W = random_spd(rng)
    G = g_from_w(W)
    np.testing.assert_allclose(w_from_g(G), W, atol=1e-12)
    R = random_rotation(rng)
    wx, wy = rng.normal(size=(2, 3))
    np.testing.assert_allclose(metric_gl(R @ skew(wx), R @ skew(wy), W), metric_so3(wx, wy, G), rtol=1e-12, atol=1e-12)


@given(seeds)
def test_se3_metric_is_the_restriction_of_ga_and_left_invariant(seed):
    """eq. (10) = eq. (9) at A in SE(3) with X = A zeta^; both invariant under A -> g A."""
    rng = np.random.default_rng(seed)
    W, w = random_spd(rng), rng.uniform(0.1, 3.0)
    A = np.eye(4)
    A[:3, :3], A[:3, 3] = random_rotation(rng), rng.normal(size=3)
    zx, zy = rng.normal(size=(2, 6))
    X, Y = A @ twist_matrix(zx), A @ twist_matrix(zy)
    ref = metric_se3(zx, zy, g_from_w(W), w)
    np.testing.assert_allclose(metric_ga(X, Y, W, w), ref, rtol=1e-11, atol=1e-11)
    g = np.eye(4)
    g[:3, :3], g[:3, 3] = random_rotation(rng), rng.normal(size=3)
    np.testing.assert_allclose(metric_ga(g @ X, g @ Y, W, w), ref, rtol=1e-11, atol=1e-11)


def test_gl_metric_is_right_invariant_only_when_bi_invariant():
    rng = np.random.default_rng(1)
    X, Y, Q = rng.normal(size=(3, 3)), rng.normal(size=(3, 3)), random_rotation(rng)
    W = np.diag([1.0, 2.0, 5.0])
    assert abs(metric_gl(X @ Q, Y @ Q, W) - metric_gl(X, Y, W)) > 1e-3
    np.testing.assert_allclose(metric_gl(X @ Q, Y @ Q, 2 * np.eye(3)), metric_gl(X, Y, 2 * np.eye(3)), rtol=1e-12)


def test_metric_input_errors():
    with pytest.raises(InvalidInputError, match="symmetric"):
        metric_gl(np.eye(3), np.eye(3), np.array([[1.0, 1.0, 0], [0, 1, 0], [0, 0, 1]]))
    with pytest.raises(InvalidInputError, match="shape"):
        metric_se3(np.zeros(5), np.zeros(6), np.eye(3), 1.0)


# --------------------------------------------------------------------------- projection


@given(seeds)
def test_projection_is_a_rotation_idempotent_and_matches_scipy(seed):
    """Proposition 2.1 against scipy.linalg.polar (det > 0) and Kabsch/align_vectors (any det)."""
    rng = np.random.default_rng(seed)
    B, W = rng.normal(size=(3, 3)), random_spd(rng)
    R = project_to_so3(B, W)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    np.testing.assert_allclose(project_to_so3(R, W), R, atol=1e-12)
    if np.linalg.det(B) > 0:
        np.testing.assert_allclose(R, polar(B @ W)[0], atol=1e-10)
    lam, E = np.linalg.eigh(W)  # Tr(R^T B W) = sum_k lam_k (R e_k) . (B e_k)
    ref, _ = Rotation.align_vectors((B @ E).T, E.T, weights=lam)
    np.testing.assert_allclose(R, ref.as_matrix(), atol=1e-8)


@given(seeds)
def test_projection_is_closest_in_the_metric(seed):
    rng = np.random.default_rng(seed)
    B, W = rng.normal(size=(3, 3)), random_spd(rng)
    R = project_to_so3(B, W)
    others = random_rotation(rng, 200)
    # also rotations near R: the optimum is local too
    near = matrix_from_q(q_from_matrix(R)) @ Rotation.from_rotvec(1e-3 * rng.normal(size=(50, 3))).as_matrix()
    assert np.all(wdist2(B, R, W) <= wdist2(B, np.concatenate([others, near]), W) + 1e-12)


@given(seeds)
def test_projection_is_left_equivariant_and_batched(seed):
    """Projecting Q B gives Q times the projection of B (the frame-invariance of [4])."""
    rng = np.random.default_rng(seed)
    B, W, Q = rng.normal(size=(4, 3, 3)), random_spd(rng), random_rotation(rng)
    R = project_to_so3(B, W)
    np.testing.assert_allclose(project_to_so3(Q @ B, W), Q @ R, atol=1e-9)
    np.testing.assert_allclose(R[2], project_to_so3(B[2], W), atol=1e-14)
    A = np.zeros((4, 4, 4))
    A[:, :3, :3], A[:, :3, 3], A[:, 3, 3] = B, rng.normal(size=(4, 3)), 1.0
    P = project_to_se3(A, W)
    np.testing.assert_allclose(P[:, :3, :3], R, atol=1e-14)
    np.testing.assert_allclose(P[:, :3, 3], A[:, :3, 3])


def test_projection_degenerate_and_special_cases():
    W = np.diag([1.0, 2.0, 3.0])
    with pytest.raises(DegenerateInputError, match="zero"):
        project_to_so3(np.zeros((3, 3)), W)
    with pytest.raises(DegenerateInputError, match="rank <= 1"):
        project_to_so3(np.outer([1.0, 2, 3], [0.5, 0, 1]), W)
    # det < 0 with equal smallest singular values: two rotations are equally close
    with pytest.raises(DegenerateInputError, match="det B1 W < 0"):
        project_to_so3(np.diag([3.0, -1.0, 1.0]), np.eye(3))
    # det < 0 but distinct: the Kabsch choice flips the smallest direction only
    np.testing.assert_allclose(project_to_so3(np.diag([3.0, 2.0, -1.0]), np.eye(3)), np.eye(3), atol=1e-15)
    # repeated singular values with det > 0: still unique (polar factor)
    np.testing.assert_allclose(project_to_so3(2 * np.eye(3), np.eye(3)), np.eye(3), atol=1e-15)
    # rank-2 W (a planar body): unique, and a rotation is its own projection
    Wp = np.diag([1.0, 2.0, 0.0])
    R = Rotation.from_rotvec([0.3, -0.2, 0.9]).as_matrix()
    np.testing.assert_allclose(project_to_so3(R, Wp), R, atol=1e-12)
    with pytest.raises(InvalidInputError, match="last row"):
        project_to_se3(2 * np.eye(4), W)


# --------------------------------------------------------------------------- rates and curves


@given(seeds)
def test_projected_rates_match_finite_differences(seed):
    rng = np.random.default_rng(seed)
    C = rng.normal(size=(3, 3, 3))
    C[0] = random_rotation(rng)  # stay near SO(3)
    W = random_spd(rng)

    def M(t):
        return C[0] + C[1] * t + C[2] * t**2

    t, h = 0.2, 1e-5
    R, om, omd = projected_rotation_rates(M(t), C[1] + 2 * C[2] * t, 2 * C[2], W)
    Rp, Rm = project_to_so3(M(t + h), W), project_to_so3(M(t - h), W)
    np.testing.assert_allclose(om, vee(R.T @ (Rp - Rm) / (2 * h)), rtol=1e-5, atol=1e-6)
    omp = projected_rotation_rates(M(t + h), C[1] + 2 * C[2] * (t + h), 2 * C[2], W)[1]
    omm = projected_rotation_rates(M(t - h), C[1] + 2 * C[2] * (t - h), 2 * C[2], W)[1]
    np.testing.assert_allclose(omd, (omp - omm) / (2 * h), rtol=1e-4, atol=1e-5)


@given(seeds, st.floats(0.05, 3.0))
def test_bi_invariant_geodesic_is_slerp_reparametrised(seed, angle):
    """W = I: the projection of R0 + (R1 - R0) t is R0 exp(phi(t) n^) with
    phi = atan2(t sin theta, 1 - t + t cos theta): the slerp path, reparametrised."""
    rng = np.random.default_rng(seed)
    R0 = random_rotation(rng)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    R1 = R0 @ Rotation.from_rotvec(angle * n).as_matrix()
    curve = ProjectedCurve.geodesic(R0, np.zeros(3), R1, np.ones(3), np.eye(3), 1.0, duration=2.0)
    t = np.linspace(0.0, 2.0, 9)
    R, om, *_ = curve.evaluate(t)
    s = t / 2.0
    phi = np.arctan2(s * np.sin(angle), 1 - s + s * np.cos(angle))
    q_ref = qslerp(q_from_matrix(R0), q_from_matrix(R1), phi / angle)
    np.testing.assert_allclose(R, matrix_from_q(q_ref), atol=1e-10)
    np.testing.assert_allclose(R[[0, -1]], [R0, R1], atol=1e-14)
    dphi = np.sin(angle) / ((1 - s + s * np.cos(angle)) ** 2 + (s * np.sin(angle)) ** 2) / 2.0
    np.testing.assert_allclose(om, dphi[:, None] * n, atol=1e-9)


def test_bi_invariant_geodesic_through_a_half_turn_is_refused():
    R1 = Rotation.from_rotvec([0.0, 0.0, np.pi]).as_matrix()
    with pytest.raises(DegenerateInputError, match="half turn"):
        ProjectedCurve.geodesic(np.eye(3), np.zeros(3), R1, np.zeros(3), np.diag([1.0, 2.0, 3.0]))
    # the midpoint of that line is rank 1: the projection itself refuses it
    with pytest.raises(DegenerateInputError, match="not unique"):
        project_to_so3(0.5 * (np.eye(3) + R1), np.diag([1.0, 2.0, 3.0]))
    # just short of a half turn: unique and continuous, the turn concentrated near t = 1/2
    R1 = Rotation.from_rotvec([0.0, 0.0, np.pi - 1e-3]).as_matrix()
    curve = ProjectedCurve.geodesic(np.eye(3), np.zeros(3), R1, np.zeros(3), np.eye(3))
    R, om, *_ = curve.evaluate(np.linspace(0, 1, 101))
    assert np.all(np.abs(np.linalg.det(R) - 1) < 1e-12) and om[50, 2] > 100


@given(seeds)
def test_min_acceleration_curve_is_eqs_13_14_with_exact_ends(seed):
    rng = np.random.default_rng(seed)
    R0, R1 = random_rotation(rng, 2)
    d0, d1, v0, v1, w0, w1 = rng.normal(size=(6, 3))
    W = random_spd(rng)
    T = 1.5
    Rd0, Rd1 = R0 @ skew(w0), R1 @ skew(w1)
    curve = ProjectedCurve.min_acceleration(R0, d0, Rd0, v0, R1, d1, Rd1, v1, W, 2.0, T)
    t = rng.uniform(0, T)
    s = t / T
    # seed eq. (13) written out (with rates per tau: T times the given ones)
    d13 = d0 + T * v0 * s + (-3 * d0 + 3 * d1 - 2 * T * v0 - T * v1) * s**2 + (2 * d0 - 2 * d1 + T * v0 + T * v1) * s**3
    M14 = R0 + T * Rd0 * s + (-3 * R0 + 3 * R1 - 2 * T * Rd0 - T * Rd1) * s**2 + (2 * R0 - 2 * R1 + T * Rd0 + T * Rd1) * s**3
    M, _, _, d, _, _ = curve.ambient(t)
    np.testing.assert_allclose(d, d13, atol=1e-12)
    np.testing.assert_allclose(M, M14, atol=1e-12)
    R, om, _, d, dd, _ = curve.evaluate(np.array([0.0, T]))
    np.testing.assert_allclose(R, [R0, R1], atol=1e-12)
    np.testing.assert_allclose(d, [d0, d1], atol=1e-12)
    # the projection keeps the end twists: omega = ((Tr W) I - W)^-1 ((Tr W) I - W) omega
    np.testing.assert_allclose(om, [w0, w1], atol=1e-10)
    np.testing.assert_allclose(dd, [v0, v1], atol=1e-12)


def test_energy_is_the_integral_of_the_ambient_metric():
    rng = np.random.default_rng(3)
    R0, R1 = random_rotation(rng, 2)
    W = random_spd(rng)
    curve = ProjectedCurve.min_acceleration(R0, np.zeros(3), R0 @ skew([1.0, 0, 0]), [1.0, 2, 3], R1,
                                            np.ones(3), np.zeros((3, 3)), np.zeros(3), W, 0.7, 2.0)
    t = np.linspace(0, 2.0, 20001)
    _, Md, _, _, dd, _ = curve.ambient(t)
    f = metric_gl(Md, Md, W) + 0.7 * np.sum(dd * dd, axis=-1)
    np.testing.assert_allclose(curve.energy(), _trapezoid(f, t), rtol=1e-7)


def test_curve_input_errors():
    bad = np.diag([1.0, 1.0, -1.0])
    with pytest.raises(NotARotationError):
        ProjectedCurve.geodesic(bad, np.zeros(3), np.eye(3), np.zeros(3), np.eye(3))
    curve = ProjectedCurve.geodesic(np.eye(3), np.zeros(3), np.eye(3), np.zeros(3), np.eye(3), duration=2.0)
    with pytest.raises(InvalidInputError, match=r"\[0, 2\]"):
        curve.evaluate(2.5)
    with pytest.raises(InvalidInputError, match="duration"):
        ProjectedCurve.geodesic(np.eye(3), np.zeros(3), np.eye(3), np.zeros(3), np.eye(3), duration=0.0)
