"""Euler parameters (seed 003): the unit quaternion in the teleoperation literature's notation.

Part of the algebra layer. Seed 003 writes a unit quaternion as ``{eps4, eps_hat}`` with
``eps4 = cos(theta/2)`` and ``eps_hat = k sin(theta/2)`` (eqs. (1)-(5)); quatform stores
it as ``(w, x, y, z) = (eps4, eps1, eps2, eps3)``. Conversions to the seed's own ordering
``(eps1, eps2, eps3, eps4)`` are provided for readers who check numbers against the paper.
"""

from __future__ import annotations

import numpy as np

from .validate import as_array, as_unit_quaternion
from .operators import skew

__all__ = [
    "euler_parameters_from_q",
    "q_from_euler_parameters",
    "relative_euler_parameters",
    "w_matrix",
]


def euler_parameters_from_q(q) -> np.ndarray:
    """``(eps1, eps2, eps3, eps4)`` of unit quaternions ``(w, x, y, z)`` (seed 003 eqs. (1)-(4))."""
    q = as_unit_quaternion(q)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def q_from_euler_parameters(eps) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` from seed 003's ``(eps1, eps2, eps3, eps4)``."""
    e = as_array(eps, "eps", 4)
    return as_unit_quaternion(np.concatenate([e[..., 3:], e[..., :3]], axis=-1), "eps")


def relative_euler_parameters(q_m, q_s) -> np.ndarray:
    """Euler parameters of ``R_M^T R_S``, the orientation of {S} seen from {M}.

    seed 003 eqs. (8)-(10)::

        d_eps_hat = eps_M eps_hat_S - eps_S eps_hat_M - [eps_hat_M]x eps_hat_S      (9)
        d_eps4    = eps_M eps_S + eps_hat_M^T eps_hat_S                             (10)

    Eq. (10) is printed as ``eps_M eps_hat_S + ...``, a typo: the first term is the product
    of the two scalars (the result is a scalar). Together they are ``q_M* q_S``.

    Parameters
    ----------
    q_m, q_s : array_like, shape (..., 4)
        Unit quaternions ``(w, x, y, z)`` of the master and slave frames in a common base.

    Returns
    -------
    ndarray, shape (..., 4)
        ``(d_eps4, d_eps_hat)`` in quatform's ``(w, x, y, z)`` layout; ``d_eps_hat`` is
        expressed in {M}.
    """
    qm = as_unit_quaternion(q_m, "q_m")
    qs = as_unit_quaternion(q_s, "q_s")
    em, vm = qm[..., :1], qm[..., 1:]
    es, vs = qs[..., :1], qs[..., 1:]
    d_vec = em * vs - es * vm - np.cross(vm, vs)  # seed 003 eq. (9)
    d_4 = em * es + np.einsum("...i,...i->...", vm, vs)[..., None]  # seed 003 eq. (10), corrected
    return np.concatenate([d_4, d_vec], axis=-1)


def w_matrix(q_m, q_s) -> np.ndarray:
    """Matrix ``W`` of seed 003 eq. (19): rate of the orientation error from angular velocity.

    ``W = 1/2 [eps_hat_S eps_hat_M^T + (eps_S I - [eps_hat_S]x)(eps_M I - [eps_hat_M]x)]``.

    What it maps (verified by finite differences in the tests): with ``d_eps_hat`` the
    vector part of :func:`relative_euler_parameters` ``(q_M, q_S)`` and both angular
    velocities expressed in the base frame,

        d/dt d_eps_hat = W (omega_S - omega_M).

    So ``J_s = diag(I, W) J_sf`` (eq. (18)) maps slave joint rates to the rate of the error
    vector, and the master's motion enters with the opposite sign.

    Equivalently ``W = 1/2 (d_eps4 I - [d_eps_hat]x) R_M^T``: its singular values are
    ``1/2, 1/2, |cos(theta/2)|/2`` for an orientation error ``theta``. It is polynomial in
    the parameters (no representation singularity, unlike Euler-angle rates); it loses rank
    only at a 180-degree error, where ``|d_eps_hat| = sin(theta/2)`` is at its maximum.

    Parameters
    ----------
    q_m, q_s : array_like, shape (..., 4)
        Unit quaternions of master and slave.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    qm = as_unit_quaternion(q_m, "q_m")
    qs = as_unit_quaternion(q_s, "q_s")
    eye = np.eye(3)
    A = qs[..., 0, None, None] * eye - skew(qs[..., 1:])
    B = qm[..., 0, None, None] * eye - skew(qm[..., 1:])
    return 0.5 * (qs[..., 1:, None] * qm[..., None, 1:] + A @ B)
