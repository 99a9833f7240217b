"""Measures of a planned motion: separations, and the two motions seed 002 compares with.

Planning layer. The shaped geodesics of seed 002 run between two extremes, both computed
here from the end configurations alone: the uniform straight lines (``alpha = 0.5``) and
the optimal rigid motion (``alpha -> 1``, seed 002 §5-§6: the centre of mass moves
uniformly on a line, the formation turns uniformly about it).
"""

from __future__ import annotations

import numpy as np

from ..algebra.quaternion import matrix_from_q, q_from_matrix, qpow

__all__ = ["min_separation", "pair_separations", "rigid_motion", "straight_line_motion"]

#: End configurations whose best rigid fit misses by more than this fraction of their size
#: are not a rigid displacement (no rigid reference motion).
RIGID_FIT_TOLERANCE = 1e-6


def pair_separations(positions) -> np.ndarray:
    """Distances between every pair of robots, shape ``(..., N, N)`` (zero diagonal)."""
    p = np.asarray(positions, dtype=float)
    return np.linalg.norm(p[..., :, None, :] - p[..., None, :, :], axis=-1)


def min_separation(positions):
    """Smallest distance between two robots over all samples: ``(distance, sample, (i, j))``."""
    D = pair_separations(positions)
    N = D.shape[-1]
    D = D + np.diag(np.full(N, np.inf))
    k = int(np.argmin(D))
    s, i, j = np.unravel_index(k, D.shape)
    return float(D.reshape(-1)[k]), int(s), (int(i), int(j))


def straight_line_motion(start, goal, s) -> np.ndarray:
    """Uniform straight lines from ``start`` to ``goal`` (shape ``(N, d)``) at fractions ``s``
    (shape ``(K,)``): the geodesic of the unshaped metric (seed 002 §3, ``alpha = 0.5``)."""
    s = np.asarray(s, dtype=float)[:, None, None]
    return (1.0 - s) * start + s * goal


def _rigid_fit(start, goal, masses):
    """Mass-weighted best rotation ``R`` with ``goal - c1 = R (start - c0)`` (Kabsch), and its miss."""
    m = masses[:, None]
    c0 = (m * start).sum(0) / m.sum()
    c1 = (m * goal).sum(0) / m.sum()
    X0, X1 = start - c0, goal - c1
    U, sv, Vt = np.linalg.svd((m * X1).T @ X0)
    D = np.eye(start.shape[1])
    D[-1, -1] = np.sign(np.linalg.det(U @ Vt))
    R = U @ D @ Vt
    if start.shape[1] == 3 and sv[1] <= 1e-12 * sv[0]:
        # collinear robots: the spin about their line is free; take the smallest rotation
        k = int(np.argmax(np.linalg.norm(X0, axis=1)))
        a, b = X0[k] / np.linalg.norm(X0[k]), X1[k] / np.linalg.norm(X1[k])
        axis, c = np.cross(a, b), float(a @ b)
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        R = np.eye(3) + K + K @ K / (1.0 + c) if c > -1.0 + 1e-12 else R
    miss = float(np.max(np.linalg.norm(X1 - X0 @ R.T, axis=1)))
    return R, c0, c1, X0, miss


def rigid_motion(start, goal, masses, s):
    """The optimal rigid motion between ``start`` and ``goal`` at fractions ``s``, or None.

    Seed 002 §5: uniform straight motion of the centre of mass and a uniform rotation about
    it, the short way. This is the geodesic of the rigid kinetic-energy metric (eq. (4))
    in the plane (SE(2)) always, and in space when the rotation axis is a principal axis of
    the formation's inertia about its centre of mass (else the SE(3) geodesic does not turn
    about a fixed axis; then None, as when the ends are not a rigid displacement).

    Returns
    -------
    ndarray, shape (K, N, d) or None
    """
    start = np.asarray(start, dtype=float)
    goal = np.asarray(goal, dtype=float)
    masses = np.asarray(masses, dtype=float)
    s = np.asarray(s, dtype=float)
    R, c0, c1, X0, miss = _rigid_fit(start, goal, masses)
    size = max(float(np.max(np.linalg.norm(X0, axis=1))), 1e-300)
    if miss > RIGID_FIT_TOLERANCE * size:
        return None
    c = (1.0 - s)[:, None] * c0 + s[:, None] * c1
    if start.shape[1] == 2:
        th = np.arctan2(R[1, 0], R[0, 0]) * s
        Rs = np.stack([np.stack([np.cos(th), -np.sin(th)], -1), np.stack([np.sin(th), np.cos(th)], -1)], -2)
    else:
        q = q_from_matrix(R)
        w = q[1:]  # rotation axis (unnormalised)
        inertia = (masses[:, None, None] * (np.einsum("ij,ij->i", X0, X0)[:, None, None] * np.eye(3)
                                            - X0[:, :, None] * X0[:, None, :])).sum(0)
        Iw = inertia @ w
        if np.linalg.norm(np.cross(Iw, w)) > 1e-9 * max(np.linalg.norm(Iw) * np.linalg.norm(w), 1e-300):
            return None
        Rs = matrix_from_q(qpow(q, s, shortest=True))
    return c[:, None, :] + np.einsum("kij,nj->kni", Rs, X0)
