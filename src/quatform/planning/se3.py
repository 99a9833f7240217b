"""Metrics on SO(3)/SE(3) inherited from GL(3)/GA(3), the projection GA(3) -> SE(3), and
projected geodesics and minimum-acceleration curves (seed 004 §2, Belta & Kumar 2001).

Planning layer: imports only :mod:`quatform.algebra` and :mod:`quatform.errors`.

The ambient metric ``<X, Y> = Tr(X^T Y W)`` on GL(3) (seed 004 eq. (5)) does not depend
on the base point: GL(3) with it is a flat Euclidean space of 3 x 3 matrices, in which
geodesics are straight lines and minimum-acceleration curves are cubics. Restricted to
SO(3) it is the left-invariant metric ``omega^T G omega`` with ``G = Tr(W) I - W``
(eqs. (6)-(7)). For a rigid body ``W = 1/2 int r r^T dm`` (half the second moment of its
mass) and ``G = H / 2`` (half its inertia): ``Tr(Xdot^T Xdot W) = 1/2 int |Xdot r|^2 dm``
is the kinetic energy of the affinely moving body. Physical bodies therefore have ``W``
positive *semi*-definite; a planar body has rank-2 ``W``, which the projection below
still handles (its rotation is unique), a collinear one rank 1, which it refuses.

Matrices are ``(..., 3, 3)`` (rotations act on column vectors, ``R`` maps the body frame
to the world frame); twists are ``(..., 6)`` vectors ``(omega, v)`` in the body frame
(seed 004 eq. (1)).

* :func:`g_from_w`, :func:`w_from_g` - eq. (7).
* :func:`metric_gl`, :func:`metric_so3`, :func:`metric_ga`, :func:`metric_se3` - eqs.
  (5), (6), (9), (10).
* :func:`project_to_so3`, :func:`project_to_se3` - Proposition 2.1 (eqs. (11)-(12)).
* :func:`projected_rotation_rates` - the projection of a moving matrix, with the body
  angular velocity and acceleration of the projected rotation (analytic derivatives).
* :class:`ProjectedCurve` - a line or a cubic in GA(3) (eqs. (13)-(14)) and its projection.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..algebra import skew
from ..algebra.validate import as_array
from ..errors import DegenerateInputError, InvalidInputError, NotARotationError

__all__ = [
    "PROJECTION_RTOL",
    "ProjectedCurve",
    "g_from_w",
    "metric_ga",
    "metric_gl",
    "metric_se3",
    "metric_so3",
    "project_to_se3",
    "project_to_so3",
    "projected_rotation_rates",
    "twist_matrix",
    "vee",
    "w_from_g",
]

#: Relative gap (to the largest singular value) below which the projection of
#: Proposition 2.1 is declared not unique: ``sigma_2 + sigma_3`` when ``det(B_1) > 0``,
#: ``sigma_2 - sigma_3`` when ``det(B_1) < 0``.
PROJECTION_RTOL = 1e-10


def _sym(W, name):
    W = as_array(W, name, (3, 3))
    asym = np.abs(W - np.swapaxes(W, -1, -2)).max(initial=0.0)
    scale = max(1.0, float(np.abs(W).max(initial=0.0)))
    if asym > 1e-9 * scale:
        raise InvalidInputError(
            f"{name} must be symmetric; max |{name} - {name}^T| = {asym:.3g}. "
            f"Use ({name} + {name}.T) / 2 if the asymmetry is round-off"
        )
    return 0.5 * (W + np.swapaxes(W, -1, -2))


def vee(S) -> np.ndarray:
    """Vector ``s`` of a 3 x 3 matrix's skew part: ``vee(s^) = s`` for skew ``s^``.

    Parameters
    ----------
    S : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 3)
        ``1/2 (S_32 - S_23, S_13 - S_31, S_21 - S_12)``.
    """
    S = as_array(S, "S", (3, 3))
    return 0.5 * np.stack(
        [S[..., 2, 1] - S[..., 1, 2], S[..., 0, 2] - S[..., 2, 0], S[..., 1, 0] - S[..., 0, 1]], axis=-1
    )


def twist_matrix(zeta) -> np.ndarray:
    """The se(3) matrix ``[[omega^, v], [0, 0]]`` of twists ``(omega, v)`` (seed 004 §2.1).

    Parameters
    ----------
    zeta : array_like, shape (..., 6)

    Returns
    -------
    ndarray, shape (..., 4, 4)
    """
    zeta = as_array(zeta, "zeta", 6)
    out = np.zeros(zeta.shape[:-1] + (4, 4))
    out[..., :3, :3] = skew(zeta[..., :3])
    out[..., :3, 3] = zeta[..., 3:]
    return out


def g_from_w(W) -> np.ndarray:
    """SO(3) metric ``G = Tr(W) I - W`` of the GL(3) metric ``W`` (seed 004 eq. (7)).

    Parameters
    ----------
    W : array_like, shape (..., 3, 3)
        Symmetric.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    W = _sym(W, "W")
    return np.trace(W, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) - W


def w_from_g(G) -> np.ndarray:
    """GL(3) metric ``W = 1/2 Tr(G) I - G`` inducing the SO(3) metric ``G`` (seed 004 eq. (7)).

    ``W`` is positive definite exactly when every eigenvalue of ``G`` is smaller than the
    sum of the other two (the strict triangle inequality of principal inertias).

    Parameters
    ----------
    G : array_like, shape (..., 3, 3)
        Symmetric.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    G = _sym(G, "G")
    return 0.5 * np.trace(G, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) - G


def metric_gl(X, Y, W) -> np.ndarray:
    """``<X, Y>_GL = Tr(X^T Y W)`` (seed 004 eq. (5)).

    Parameters
    ----------
    X, Y : array_like, shape (..., 3, 3)
        Tangent vectors (any 3 x 3 matrices: GL(3) is open in R^{3x3}).
    W : array_like, shape (..., 3, 3)
        Symmetric metric matrix.

    Returns
    -------
    ndarray, shape (...)
    """
    X = as_array(X, "X", (3, 3))
    Y = as_array(Y, "Y", (3, 3))
    W = _sym(W, "W")
    return np.einsum("...ki,...kj,...ji->...", X, Y, W)


def metric_so3(omega_x, omega_y, G) -> np.ndarray:
    """``<X, Y>_SO = omega_x^T G omega_y`` for ``X = R omega_x^``, ``Y = R omega_y^``
    (seed 004 eq. (6)).

    Parameters
    ----------
    omega_x, omega_y : array_like, shape (..., 3)
        Body angular velocities.
    G : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (...)
    """
    wx = as_array(omega_x, "omega_x", 3)
    wy = as_array(omega_y, "omega_y", 3)
    G = _sym(G, "G")
    return np.einsum("...i,...ij,...j->...", wx, G, wy)


def metric_ga(X, Y, W, w) -> np.ndarray:
    """``<X, Y>_GA = Tr(X^T Y W~)`` with ``W~ = diag(W, w)`` (seed 004 eqs. (8)-(9)).

    Parameters
    ----------
    X, Y : array_like, shape (..., 4, 4)
        Tangent vectors of GA(3): last row zero (it is ignored).
    W : array_like, shape (..., 3, 3)
    w : float or array_like, shape (...)

    Returns
    -------
    ndarray, shape (...)
        ``Tr(X_1^T Y_1 W) + w X_2 . Y_2`` for the blocks ``X_1`` (3 x 3) and ``X_2`` (3).
    """
    X = as_array(X, "X", (4, 4))
    Y = as_array(Y, "Y", (4, 4))
    w = as_array(w, "w", None)
    return metric_gl(X[..., :3, :3], Y[..., :3, :3], W) + w * np.einsum(
        "...i,...i->...", X[..., :3, 3], Y[..., :3, 3]
    )


def metric_se3(zeta_x, zeta_y, G, w) -> np.ndarray:
    """``<X, Y>_SE = zeta_x^T diag(G, w I) zeta_y`` (seed 004 eq. (10)).

    The squared norm is the kinetic energy of a body of mass ``2 w`` and inertia ``2 G``
    about its centroid, moving with body twist ``zeta``.

    Parameters
    ----------
    zeta_x, zeta_y : array_like, shape (..., 6)
        Body twists ``(omega, v)``.
    G : array_like, shape (..., 3, 3)
    w : float or array_like, shape (...)

    Returns
    -------
    ndarray, shape (...)
    """
    zx = as_array(zeta_x, "zeta_x", 6)
    zy = as_array(zeta_y, "zeta_y", 6)
    w = as_array(w, "w", None)
    return metric_so3(zx[..., :3], zy[..., :3], G) + w * np.einsum("...i,...i->...", zx[..., 3:], zy[..., 3:])


def _svd_projection(N, rtol, name):
    """``R = U diag(1, 1, d) V^T`` of ``N = U S V^T``, d = det(U V^T); raise if not unique.

    Returns ``R``, the signed singular values ``S diag(1, 1, d)`` and ``V^T``.
    """
    U, s, Vt = np.linalg.svd(N)
    d = np.sign(np.linalg.det(U) * np.linalg.det(Vt))
    top = s[..., 0]
    gap = np.where(d > 0, s[..., 1] + s[..., 2], s[..., 1] - s[..., 2])
    bad = ~(gap > rtol * top)  # also catches top == 0
    if np.any(bad):
        k = int(np.argmax(np.ravel(bad)))
        sv, dk = s.reshape(-1, 3)[k], np.ravel(d)[k]
        where = f" at index {np.unravel_index(k, bad.shape)}" if bad.ndim else ""
        if sv[0] == 0.0:
            why = f"{name} is zero"
        elif dk > 0:
            why = f"{name} has rank <= 1 (singular values {sv[0]:.6g}, {sv[1]:.3g}, {sv[2]:.3g})"
        else:
            why = f"det {name} < 0 and its two smallest singular values are equal ({sv[1]:.9g}, {sv[2]:.9g})"
        raise DegenerateInputError(
            f"the closest rotation to B_1 in the metric W is not unique{where}: {why}. "
            "For a curve, the ambient matrix passed through a degenerate point: choose end "
            "rotations less than a half turn apart, or a W of rank >= 2 (a formation whose "
            "points are not collinear)"
        )
    D = np.ones(s.shape)
    D[..., 2] = d
    R = (U * D[..., None, :]) @ Vt
    return R, s * D, Vt


def project_to_so3(B1, W, rtol: float = PROJECTION_RTOL) -> np.ndarray:
    """Closest rotation to ``B1`` in the metric ``Tr(X^T X W)``: Proposition 2.1 of seed 004.

    With ``B1 W = U S V^T`` (eq. (11)) the closest element of SO(3) is ``U D V^T``,
    ``D = diag(1, 1, det(U V^T))``: eq. (12)'s ``U V^T`` when ``det B1 > 0``; when
    ``det B1 < 0`` (``U V^T`` would be a reflection) the sign of the smallest singular
    direction is flipped, which maximises ``Tr(R^T B1 W)`` over SO(3) (the Kabsch
    correction; seed 004 leaves this case out). ``B1`` may be singular.

    Parameters
    ----------
    B1 : array_like, shape (..., 3, 3)
    W : array_like, shape (..., 3, 3)
        Symmetric positive semi-definite metric matrix.
    rtol : float
        Relative singular-value gap below which the result is declared not unique.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Rotation matrices.

    Raises
    ------
    DegenerateInputError
        Where the closest rotation is not unique: ``B1 W`` of rank <= 1 when
        ``det(B1 W) >= 0``, or equal two smallest singular values when ``det(B1 W) < 0``.
    """
    B1 = as_array(B1, "B1", (3, 3))
    W = _sym(W, "W")
    return _svd_projection(B1 @ W, rtol, "B1 W")[0]


def project_to_se3(B, W, rtol: float = PROJECTION_RTOL) -> np.ndarray:
    """Projection of ``B = [[B1, B2], [0, 1]]`` in GA(3) onto SE(3) (seed 004 eq. (12)).

    The rotation block is :func:`project_to_so3` of ``B1``; the translation ``B2`` is kept
    (the metric's translational part ``w`` does not couple to rotations).

    Parameters
    ----------
    B : array_like, shape (..., 4, 4)
        Affine matrices; the last row must be ``(0, 0, 0, 1)``.
    W : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 4, 4)
    """
    B = as_array(B, "B", (4, 4))
    last = np.abs(B[..., 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(initial=0.0)
    if last > 1e-12:
        raise InvalidInputError(
            f"B must be an affine matrix with last row (0, 0, 0, 1); it deviates by {last:.3g}"
        )
    A = np.zeros(B.shape)
    A[..., :3, :3] = project_to_so3(B[..., :3, :3], W, rtol)
    A[..., :3, 3] = B[..., :3, 3]
    A[..., 3, 3] = 1.0
    return A


def projected_rotation_rates(M, M_dot, M_ddot, W, rtol: float = PROJECTION_RTOL):
    """Projection ``R(t)`` of a moving matrix ``M(t)`` and the body rates of ``R(t)``.

    With ``N = M W = R P`` (``P = R^T N`` symmetric), differentiating gives
    ``R^T Ndot - Ndot^T R = Omega P + P Omega`` for ``Omega = R^T Rdot = omega^``, and
    ``omega^ P + P omega^ = ((Tr P) I - P) omega`` (hat of), so
    ``omega = ((Tr P) I - P)^-1 vee(R^T Ndot - Ndot^T R)``. One more derivative gives
    ``omegadot`` from ``Omegadot P + P Omegadot = Kdot - Omega Pdot - Pdot Omega``. The
    matrix ``(Tr P) I - P`` is invertible exactly where the projection is unique.

    Parameters
    ----------
    M, M_dot, M_ddot : array_like, shape (..., 3, 3)
        The curve in GL(3) and its first two derivatives.
    W : array_like, shape (3, 3)

    Returns
    -------
    R : ndarray, shape (..., 3, 3)
    omega : ndarray, shape (..., 3)
        Body angular velocity ``vee(R^T Rdot)``.
    omega_dot : ndarray, shape (..., 3)
        Its derivative.
    """
    M = as_array(M, "M", (3, 3))
    Md = as_array(M_dot, "M_dot", (3, 3))
    Mdd = as_array(M_ddot, "M_ddot", (3, 3))
    W = _sym(W, "W")
    N, Nd, Ndd = M @ W, Md @ W, Mdd @ W
    R, sd, Vt = _svd_projection(N, rtol, "M W")
    Rt = np.swapaxes(R, -1, -2)
    P = (np.swapaxes(Vt, -1, -2) * sd[..., None, :]) @ Vt  # V D S V^T = R^T N
    A = np.trace(P, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) - P
    RtNd = Rt @ Nd
    K = RtNd - np.swapaxes(RtNd, -1, -2)
    omega = np.linalg.solve(A, vee(K)[..., None])[..., 0]
    Om = skew(omega)
    Pd = RtNd - Om @ P
    RtNdd = Rt @ Ndd
    Kd = -Om @ RtNd + RtNdd - np.swapaxes(RtNdd, -1, -2) - np.swapaxes(RtNd, -1, -2) @ Om
    rhs = Kd - Om @ Pd - Pd @ Om
    omega_dot = np.linalg.solve(A, vee(rhs)[..., None])[..., 0]
    return R, omega, omega_dot


# --------------------------------------------------------------------------- curves

#: Monomial coefficients (rows: 1, t, t^2, t^3) of the cubic Hermite basis
#: ``(p0, v0, p1, v1)``: seed 004 eqs. (13)-(14).
HERMITE_BASIS = np.array(
    [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [-3.0, -2.0, 3.0, -1.0],
        [2.0, 1.0, -2.0, 1.0],
    ]
)


def _check_rotation(R, name):
    R = as_array(R, name, (3, 3))
    err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(initial=0.0)
    det = np.linalg.det(R)
    if err > 1e-6 or np.any(np.abs(det - 1.0) > 1e-6):
        raise NotARotationError(
            f"{name} is not a rotation matrix: max|R^T R - I| = {err:.3g}, det = {np.ravel(det)[0]:.6g}; "
            "orthonormalise it (e.g. project_to_so3(R, eye(3))) and make det = +1"
        )
    return R


@dataclass(frozen=True)
class ProjectedCurve:
    """A cubic ``(M(tau), d(tau))`` in GA(3), ``tau = t / duration`` in ``[0, 1]``, and its
    projection onto SE(3) (seed 004 §2.4).

    Build it with :meth:`geodesic` (straight line: the GA(3) geodesic) or
    :meth:`min_acceleration` (cubic Hermite: the GA(3) minimum-acceleration curve, eqs.
    (13)-(14)). ``M`` is projected with the metric ``W`` (Proposition 2.1); the
    translation ``d`` is kept.

    Attributes
    ----------
    m_coeffs : ndarray, shape (4, 3, 3)
        Monomial coefficients of ``M(tau) = sum_k m_coeffs[k] tau^k``.
    d_coeffs : ndarray, shape (4, 3)
        Monomial coefficients of ``d(tau)``.
    W : ndarray, shape (3, 3)
        GL(3) metric (eq. (5)).
    w : float
        Translational weight (eq. (8)).
    duration : float
        Seconds from ``tau = 0`` to ``tau = 1``.
    """

    m_coeffs: np.ndarray
    d_coeffs: np.ndarray
    W: np.ndarray
    w: float
    duration: float = 1.0

    @classmethod
    def geodesic(cls, R0, d0, R1, d1, W, w: float = 1.0, duration: float = 1.0) -> ProjectedCurve:
        """Straight line ``M = R0 + (R1 - R0) tau``, ``d = d0 + (d1 - d0) tau`` (seed 004 §2.4)."""
        R0, R1 = _check_rotation(R0, "R0"), _check_rotation(R1, "R1")
        d0, d1 = as_array(d0, "d0", 3), as_array(d1, "d1", 3)
        # Q = R0^T R1 a half turn about n: M(1/2) = R0 (I + Q) / 2 = R0 n n^T has rank 1,
        # so M W has rank 1 for every W and the projection is not unique there.
        cos_angle = 0.5 * (np.trace(R0.T @ R1) - 1.0)
        if cos_angle < -1.0 + 1e-12:
            raise DegenerateInputError(
                f"R0 and R1 are a half turn apart (cos angle = {cos_angle:.15f}): the line between "
                "them passes through a rank-1 matrix at its midpoint, where no closest rotation is "
                "unique; split the motion at an intermediate rotation"
            )
        z3, z = np.zeros((3, 3)), np.zeros(3)
        return cls(
            np.stack([R0, R1 - R0, z3, z3]), np.stack([d0, d1 - d0, z, z]), _sym(W, "W"), float(w),
            _positive(duration, "duration"),
        )

    @classmethod
    def min_acceleration(cls, R0, d0, R0_dot, d0_dot, R1, d1, R1_dot, d1_dot, W, w: float = 1.0,
                         duration: float = 1.0) -> ProjectedCurve:
        """Cubic Hermite ``M(tau)``, ``d(tau)`` with the given end values and rates
        (seed 004 eqs. (13)-(14)); rates are per second (``dM/dt``, ``dd/dt``)."""
        T = _positive(duration, "duration")
        R0, R1 = _check_rotation(R0, "R0"), _check_rotation(R1, "R1")
        ends_m = np.stack([R0, T * as_array(R0_dot, "R0_dot", (3, 3)), R1, T * as_array(R1_dot, "R1_dot", (3, 3))])
        ends_d = np.stack([as_array(d0, "d0", 3), T * as_array(d0_dot, "d0_dot", 3), as_array(d1, "d1", 3),
                           T * as_array(d1_dot, "d1_dot", 3)])
        return cls(
            np.einsum("kj,j...->k...", HERMITE_BASIS, ends_m), np.einsum("kj,j...->k...", HERMITE_BASIS, ends_d),
            _sym(W, "W"), float(w), T,
        )

    def _tau(self, t):
        t = as_array(t, "t", None)
        tau = t / self.duration
        if np.any((tau < -1e-9) | (tau > 1.0 + 1e-9)):
            raise InvalidInputError(
                f"t must lie in [0, {self.duration:g}] s; got values from {t.min():.6g} to {t.max():.6g}"
            )
        return np.clip(tau, 0.0, 1.0)

    def ambient(self, t):
        """``M``, ``dM/dt``, ``d^2M/dt^2``, ``d``, ``dd/dt``, ``d^2d/dt^2`` at times ``t`` (s).

        Returns arrays of shapes ``(..., 3, 3)`` (three) and ``(..., 3)`` (three).
        """
        tau = self._tau(t)
        T = self.duration
        p = tau[..., None] ** np.arange(4)  # (..., 4)
        dp = np.stack([np.zeros_like(tau), np.ones_like(tau), 2 * tau, 3 * tau**2], axis=-1) / T
        ddp = np.stack([np.zeros_like(tau), np.zeros_like(tau), 2 * np.ones_like(tau), 6 * tau], axis=-1) / T**2
        out = []
        for c in (self.m_coeffs, self.d_coeffs):
            for basis in (p, dp, ddp):
                out.append(np.tensordot(basis, c, axes=(-1, 0)))
        M, Md, Mdd, d, dd, ddd = out
        return M, Md, Mdd, d, dd, ddd

    def evaluate(self, t):
        """The projected motion at times ``t`` (s).

        Returns
        -------
        R : ndarray, shape (..., 3, 3)
        omega : ndarray, shape (..., 3)
            Body angular velocity (rad/s).
        omega_dot : ndarray, shape (..., 3)
            Body angular acceleration (rad/s^2).
        d, d_dot, d_ddot : ndarray, shape (..., 3)
            Position, velocity, acceleration of the origin (world frame).
        """
        M, Md, Mdd, d, dd, ddd = self.ambient(t)
        R, om, omd = projected_rotation_rates(M, Md, Mdd, self.W)
        return R, om, omd, d, dd, ddd

    def energy(self) -> float:
        """``int_0^T Tr(Mdot^T Mdot W) + w |ddot|^2 dt`` of the ambient curve (seed 004 §3.2), J.

        Exact (Gauss-Legendre quadrature with 3 nodes integrates the quartic integrand).
        """
        x, wts = np.polynomial.legendre.leggauss(3)
        t = 0.5 * (x + 1.0) * self.duration
        _, Md, _, _, dd, _ = self.ambient(t)
        f = metric_gl(Md, Md, self.W) + self.w * np.einsum("...i,...i->...", dd, dd)
        return float(0.5 * self.duration * np.dot(wts, f))


def _positive(x, name) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be a number, got {x!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise InvalidInputError(f"{name} must be a finite number > 0, got {x!r}")
    return v
