"""Kinetic-energy shaping for N point robots (seed 002 §3-§4): the shaped metric and its connection.

Planning layer (above algebra and formations; never imports sim, report or cli).
Configurations are stacked positions ``q = (q_1, ..., q_N)``, shape ``(..., N*d)`` with
``d = 2`` (planar, the seed's examples) or ``d = 3``; ``masses`` has shape ``(N,)``.

The seed splits every velocity into a rigid part (``Ver``, the range of ``A(q)``, eq. (6))
and a part that deforms the formation (``Hor``, its complement in the kinetic-energy metric,
eq. (7)), and weights the two (eqs. (11)-(13)). Everything here works in *mass-weighted*
coordinates ``u = L q̇`` with ``L = diag(sqrt(m_i))``: there the kinetic-energy metric is the
identity, ``Ver`` has the Euclidean orthogonal projector ``P = A' A'^+`` (``A' = L A``,
pseudo-inverse by SVD, so no coordinate is ever divided by, unlike the seed's hand-written
``B``), and

    M_alpha = (1 - alpha) L P L + alpha L (I - P) L = alpha M + (1 - 2 alpha) L P L,

with the weights of eq. (11) (eq. (13) as printed swaps them: ``docs/derivations.md``,
seed 002 item 1). The metric is ``M = diag(m_i I_d)`` (the seed's eq. (5) carries a factor
1/2 that changes neither the geodesics nor the Christoffel symbols).

The rank of ``A`` is 3 in the plane, 6 in space, and 5 in space when the robots are
collinear (always for N = 2: the spin about the segment moves no point mass). Rank is
decided with a relative tolerance; where all robots coincide the split is undefined and
:class:`~quatform.errors.DegenerateInputError` is raised.
"""

from __future__ import annotations

import functools

import numpy as np

from ..algebra._validate import as_array
from ..errors import DegenerateInputError, InvalidInputError, ShapeError

__all__ = [
    "check_alpha",
    "check_masses",
    "christoffel_symbols",
    "geodesic_acceleration",
    "horizontal_basis",
    "metric_energy",
    "rigid_generators",
    "shaped_metric",
    "shaped_metric_derivative",
    "shaped_metric_inverse",
]

#: Singular values of ``L A`` below this fraction of the largest count as zero (rank of ``A``).
RANK_TOLERANCE = 1e-9


def check_masses(masses) -> np.ndarray:
    """Masses as a finite positive ``(N,)`` array with ``N >= 2``."""
    m = as_array(masses, "masses", None)
    if m.ndim != 1 or m.size < 2:
        raise ShapeError(f"masses must be a 1-D array of N >= 2 robot masses, got shape {m.shape}")
    if np.any(m <= 0):
        raise InvalidInputError(f"masses must be positive, got {m.tolist()}; give each robot's mass in kg")
    return m


def check_alpha(alpha) -> float:
    """The shaping weight, ``0 < alpha < 1`` (seed 002 §4: 0 and 1 make the metric singular)."""
    try:
        a = float(alpha)
    except (TypeError, ValueError):
        raise InvalidInputError(f"alpha must be a number in (0, 1), got {alpha!r}") from None
    if not 0.0 < a < 1.0:
        raise InvalidInputError(
            f"alpha = {alpha!r} is outside (0, 1); alpha = 0 and 1 make the shaped metric singular "
            "(seed 002 §4): use e.g. 0.01 or 0.99"
        )
    return a


def _dims(q, masses):
    m = check_masses(masses)
    q = as_array(q, "q", None)
    n = q.shape[-1] if q.ndim else 0
    N = m.size
    if q.ndim == 0 or n not in (2 * N, 3 * N):
        raise ShapeError(
            f"q must have shape (..., N*d) with N = {N} robots (len(masses)) and d = 2 or 3, "
            f"got shape {q.shape}"
        )
    return q, m, n // N


@functools.cache
def _rotation_tensor(N: int, d: int) -> np.ndarray:
    """``G`` with ``A_rot(v) = sum_k v_k G[k]``: the rotation columns of eq. (6), linear in ``q``.

    Shape ``(N*d, N*d, r)``, ``r = 1`` (plane) or 3 (space). Column ``omega`` of robot i is
    ``omega x q_i`` (eq. (6): ``-hat(q_i) omega``).
    """
    n = N * d
    if d == 2:
        G = np.zeros((n, n, 1))
        for i in range(N):
            # seed 002 §5: rows of robot i are (-y_i, x_i) in the rotation column
            G[2 * i + 1, 2 * i, 0] = -1.0  # d(-y_i)/dy_i, x row of robot i
            G[2 * i, 2 * i + 1, 0] = 1.0  # d(x_i)/dx_i, y row of robot i
        return G
    G = np.zeros((n, n, 3))
    for i in range(N):
        for k in range(3):
            e = np.zeros(3)
            e[k] = 1.0
            # d/dq_ik of (omega x q_i) = omega x e_k = -hat(e_k) omega
            G[3 * i + k, 3 * i:3 * i + 3, :] = -_hat(e)
    return G


def _hat(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def rigid_generators(q, masses) -> np.ndarray:
    """``A(q)`` of seed 002 eq. (6): columns are the infinitesimal rigid motions at ``q``.

    Returns shape ``(..., N*d, 3)`` in the plane (rotation about z, then x and y
    translations, as in §5) or ``(..., N*d, 6)`` in space (rotations about x, y, z, then
    translations).
    """
    q, m, d = _dims(q, masses)
    N = m.size
    G = _rotation_tensor(N, d)
    rot = np.einsum("...k,kir->...ir", q, G)
    trans = np.broadcast_to(np.tile(np.eye(d), (N, 1)), q.shape[:-1] + (N * d, d))
    return np.concatenate([rot, trans], axis=-1)


def _split(q, m, d):
    """Weighted SVD pieces: ``L`` diag, ``P``, ``A'^+``, and the full left singular basis."""
    N = m.size
    sq = np.repeat(np.sqrt(m), d)
    A = rigid_generators(q, m)
    Aw = sq[:, None] * A
    U, s, Vt = np.linalg.svd(Aw, full_matrices=True)
    k = s.shape[-1]
    keep = s > RANK_TOLERANCE * s[..., :1]
    rank = keep.sum(axis=-1)
    if np.any(rank <= d):
        raise DegenerateInputError(
            "all robots coincide (no rotation is defined), so the rigid/non-rigid split of seed 002 "
            "eq. (7) is undefined; separate the robots' start and goal positions"
        )
    Uk = U[..., :, :k] * keep[..., None, :]
    P = Uk @ np.swapaxes(Uk, -1, -2)
    inv_s = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    Apinv = np.swapaxes(Vt, -1, -2) @ (inv_s[..., :, None] * np.swapaxes(U[..., :, :k], -1, -2))
    return sq, P, Apinv, U, rank, N


def horizontal_basis(q, masses) -> np.ndarray:
    """``B(q)``: a basis of ``Hor_q = Null(A^T M)`` (seed 002 eq. (7)), orthonormal in ``M``.

    Computed from the SVD of ``L A`` (never dividing by a coordinate, unlike §5-§6).
    ``B^T M B = I`` and ``A^T M B = 0``. Shape ``(N*d, N*d - rank A)``; ``q`` is one
    configuration (the rank may differ between configurations).
    """
    q, m, d = _dims(q, masses)
    if q.ndim != 1:
        raise ShapeError(f"horizontal_basis takes one configuration, shape (N*d,), got {q.shape}")
    sq, _, _, U, rank, _ = _split(q, m, d)
    return U[:, int(rank):] / sq[:, None]


def shaped_metric(q, masses, alpha) -> np.ndarray:
    """``M_alpha(q)``, shape ``(..., n, n)``: seed 002 eq. (13) with eq. (11)'s weights.

    ``alpha`` weights the deforming (horizontal) energy, ``1 - alpha`` the rigid one, so
    ``alpha -> 1`` keeps the formation rigid and ``alpha = 0.5`` gives ``M / 2``.
    """
    q, m, d = _dims(q, masses)
    a = check_alpha(alpha)
    sq, P, *_ = _split(q, m, d)
    Lm = np.diag(sq * sq)
    return a * Lm + (1.0 - 2.0 * a) * sq[:, None] * P * sq[None, :]


def shaped_metric_inverse(q, masses, alpha) -> np.ndarray:
    """``M_alpha^-1 = L^-1 (P / (1 - alpha) + (I - P) / alpha) L^-1`` (exact, no matrix inverse)."""
    q, m, d = _dims(q, masses)
    a = check_alpha(alpha)
    sq, P, *_ = _split(q, m, d)
    n = sq.size
    core = P / (1.0 - a) + (np.eye(n) - P) / a
    return core / sq[:, None] / sq[None, :]


def _dP(P, Apinv, sq, G, dv):
    """Derivative of the projector ``P`` along ``dv`` (constant rank):
    ``dP = (I - P) dA' A'^+ + its transpose`` with ``dA' = L A_rot(dv)``."""
    r = G.shape[-1]
    dA = sq[:, None] * np.einsum("...k,kir->...ir", dv, G)  # (..., n, r)
    X = dA @ Apinv[..., :r, :]  # (..., n, n)
    X = X - P @ X
    return X + np.swapaxes(X, -1, -2)


def shaped_metric_derivative(q, masses, alpha) -> np.ndarray:
    """``dM[..., h, i, j] = d m_ij / d x_h`` of ``M_alpha``, shape ``(..., n, n, n)``."""
    q, m, d = _dims(q, masses)
    a = check_alpha(alpha)
    sq, P, Apinv, *_ = _split(q, m, d)
    n = sq.size
    G = _rotation_tensor(m.size, d)
    eye = np.eye(n)
    dP = _dP(P[..., None, :, :], Apinv[..., None, :, :], sq, G, eye)  # (..., n, n, n)
    return (1.0 - 2.0 * a) * sq[:, None] * dP * sq[None, :]


def christoffel_symbols(q, masses, alpha) -> np.ndarray:
    """Christoffel symbols of ``M_alpha``, seed 002 eq. (16): ``G[..., k, i, j] = Gamma^k_ij``.

    ``Gamma^k_ij = 1/2 sum_h m^kh (d_i m_hj + d_j m_ih - d_h m_ij)`` (eq. (16) with the
    inverse metric's index on the free index ``k``), from the exact derivative of the
    projector. Shape ``(..., n, n, n)``.
    """
    dM = shaped_metric_derivative(q, masses, alpha)
    Minv = shaped_metric_inverse(q, masses, alpha)
    # first-kind symbols [h, i, j] = 1/2 (d_i m_hj + d_j m_hi - d_h m_ij)
    di_mhj = np.swapaxes(dM, -3, -2)  # [i, h, j] -> index as [h, i, j]
    dj_mhi = np.moveaxis(dM, -3, -1)  # dM[j, h, i] -> [h, i, j]
    first = 0.5 * (di_mhj + dj_mhi - dM)
    return np.einsum("...kh,...hij->...kij", Minv, first)


def geodesic_acceleration(q, q_dot, masses, alpha) -> np.ndarray:
    """``q_ddot = -Gamma(q)[q_dot, q_dot]`` (seed 002 eq. (15)) without forming ``Gamma``.

    Euler-Lagrange form ``M_a q̈ = -(dM_a[q̇]) q̇ + 1/2 grad_q (q̇^T M_a q̇)`` with the exact
    projector derivative; cost ``O(n^2)`` per configuration instead of ``O(n^3)``.
    ``q``, ``q_dot``: shape ``(..., n)``; returns shape ``(..., n)``.
    """
    q, m, d = _dims(q, masses)
    a = check_alpha(alpha)
    qd = as_array(q_dot, "q_dot", q.shape[-1])
    sq, P, Apinv, *_ = _split(q, m, d)
    G = _rotation_tensor(m.size, d)
    r = G.shape[-1]
    u = sq * qd
    z = np.einsum("...ij,...j->...i", Apinv, u)  # twist of the rigid part (seed 002 eq. (9))
    w = u - np.einsum("...ij,...j->...i", P, u)  # horizontal part, weighted
    # (dP[q̇]) u = (I - P) L A_rot(q̇) z_rot + A'^+T (L A_rot(q̇))^T w
    Arot_qd = sq[:, None] * np.einsum("...k,kir->...ir", qd, G)
    x = np.einsum("...ir,...r->...i", Arot_qd, z[..., :r])
    x = x - np.einsum("...ij,...j->...i", P, x)
    y = np.einsum("...ir,...i->...r", Arot_qd, w)
    x = x + np.einsum("...ri,...r->...i", Apinv[..., :r, :], y)
    # grad_k (u^T P u) = 2 w^T L A_rot(e_k) z_rot
    grad = 2.0 * np.einsum("kir,...i,...r->...k", G, sq * w, z[..., :r])
    c = 1.0 - 2.0 * a
    rhs = -c * (sq * x) + 0.5 * c * grad
    # M_a^-1 rhs = L^-1 (P/(1-a) + (I-P)/a) L^-1 rhs
    v = rhs / sq
    Pv = np.einsum("...ij,...j->...i", P, v)
    return (Pv / (1.0 - a) + (v - Pv) / a) / sq


def metric_energy(q, q_dot, masses, alpha) -> np.ndarray:
    """``q̇^T M_alpha(q) q̇``, shape ``(...)``: constant along a geodesic."""
    q, m, d = _dims(q, masses)
    a = check_alpha(alpha)
    qd = as_array(q_dot, "q_dot", q.shape[-1])
    sq, P, *_ = _split(q, m, d)
    u = sq * qd
    Pu = np.einsum("...ij,...j->...i", P, u)
    return (1.0 - a) * np.einsum("...i,...i->...", Pu, Pu) + a * np.einsum("...i,...i->...", u - Pu, u - Pu)
