"""Dual quaternions: rigid poses, products, conjugates, log/exp/power, the two square roots.

Part of the algebra layer, built on :mod:`quatform.algebra.quaternion`.

Layout: ``(..., 8)`` arrays, primary (real) part ``r = (w, x, y, z)`` first, then the dual
part ``d``. A pose with rotation ``q`` and translation ``t`` (in the parent frame) is
``q + eps 1/2 t q`` (seed 000 §3.3), the same layout as dqrobotics' ``vec8`` and
pytransform3d's dual quaternions.

Two powers exist, and both are provided:

* the **screw** power :func:`dqpow` (``exp(a log q)`` in the dual-quaternion algebra):
  ``dqpow(q, 1/2)`` squared is ``q``; the motion follows the screw, so the translation of
  the half power is *not* half the translation unless the translation is along the
  rotation axis. pytransform3d's ``dual_quaternion_power`` computes this one.
* the **decoupled** power :func:`dqpow_decoupled`: rotation ``r^a`` and translation
  ``a t``. Its half has exactly half the translation (the midpoint), but its square is not
  ``q`` in general. dqrobotics' ``log``/``exp``/``pow`` compute this one.

Seed 000 eq. (26) places the cluster frame ``q2 (q2* q1)^(1/2)`` *midway* between the
robots; only the decoupled root does that (see :func:`dqsqrt_decoupled` and
``docs/derivations.md``).
"""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from . import kernels
from .validate import (
    as_array,
    as_dual_quaternion,
    as_unit_dual_quaternion,
    as_unit_quaternion,
    divide_by_dual_norm,
)
from .quaternion import dot_last, nonzero_norm, norm3, sinc, qcanonical, qconj, qexp, qlog, qmul, qrotate

__all__ = [
    "DQ_IDENTITY",
    "dqmul",
    "dqconj",
    "dqconj_dual",
    "dqconj_combined",
    "dqnorm",
    "dqnormalize",
    "dqinv",
    "dqexp",
    "dqlog",
    "dqpow",
    "dqexp_decoupled",
    "dqlog_decoupled",
    "dqpow_decoupled",
    "dqsqrt_screw",
    "dqsqrt_decoupled",
    "dq_from_pose",
    "pose_from_dq",
    "dq_transform_point",
    "dqcanonical",
    "dq_closest",
]

#: The identity dual quaternion ``1 + eps 0``.
DQ_IDENTITY = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])

_QCONJ = np.array([1.0, -1.0, -1.0, -1.0])

#: Below this ``sin(a)`` a primary part next to -1 is treated as -1 in :func:`dqlog`; it
#: balances the perturbation of ``r`` against the ``eps / sin(a)`` rounding gain.
_SIN_FLOOR = 1e-8


def _join(r, d):
    return np.concatenate(np.broadcast_arrays(r, d), axis=-1)


def dqmul(a, b) -> np.ndarray:
    """Dual-quaternion product ``a b = r_a r_b + eps (r_a d_b + d_a r_b)``.

    Parameters
    ----------
    a, b : array_like, shape (..., 8)

    Returns
    -------
    ndarray, shape (..., 8)
    """
    a = as_dual_quaternion(a, "a")
    b = as_dual_quaternion(b, "b")
    return kernels.run_blocked(kernels.dqmul_components, (a, b), 8)


def dqconj(dq) -> np.ndarray:
    """Quaternion conjugate of both parts, ``r* + eps d*``: the inverse of a unit dual quaternion.

    dqrobotics ``conj``; pytransform3d ``dq_q_conj``. Shape (..., 8).
    """
    return as_dual_quaternion(dq) * np.concatenate([_QCONJ, _QCONJ])


def dqconj_dual(dq) -> np.ndarray:
    """Dual-number conjugate ``r - eps d`` (dqrobotics ``sharp``)."""
    return as_dual_quaternion(dq) * np.array([1.0] * 4 + [-1.0] * 4)


def dqconj_combined(dq) -> np.ndarray:
    """Combined conjugate ``r* - eps d*``; pytransform3d ``dq_conj``.

    ``dq (1 + eps v) dqconj_combined(dq)`` transforms the point ``v``.
    """
    return as_dual_quaternion(dq) * np.concatenate([_QCONJ, -_QCONJ])


def _primary_norm(r, name):
    return nonzero_norm(r, name, "a zero primary part", "such a dual quaternion has no norm, inverse or pose")


def dqnorm(dq) -> np.ndarray:
    """Dual-number norm ``||r|| + eps (r . d)/||r||`` (so that its square is ``dq dq*``).

    Parameters
    ----------
    dq : array_like, shape (..., 8)
        Primary part nonzero.

    Returns
    -------
    ndarray, shape (..., 2)
        ``(real, dual)`` parts of the norm; ``(1, 0)`` for unit dual quaternions.
    """
    dq = as_dual_quaternion(dq)
    n = _primary_norm(dq[..., :4], "dq")
    return np.stack([n, dot_last(dq[..., :4], dq[..., 4:]) / n], axis=-1)


def dqnormalize(dq) -> np.ndarray:
    """Unit dual quaternion ``dq / ||dq||`` (division by the dual-number norm).

    ``r' = r/||r||``, ``d' = d/||r|| - (r' . d/||r||) r'``, so ``||r'|| = 1`` and ``r' . d' = 0``.

    Raises
    ------
    DegenerateInputError
        If some primary part is zero.
    """
    dq = as_dual_quaternion(dq)
    r, d = dq[..., :4], dq[..., 4:]
    return divide_by_dual_norm(r, d, _primary_norm(r, "dq"))


def dqinv(dq) -> np.ndarray:
    """Inverse of dual quaternions with nonzero primary part; ``dqconj`` for unit ones.

    ``dq^-1 = dq* (dq dq*)^-1`` with ``dq dq* = ||r||^2 + eps 2 (r . d)``.
    """
    dq = as_dual_quaternion(dq)
    r, d = dq[..., :4], dq[..., 4:]
    n2 = (_primary_norm(r, "dq") ** 2)[..., None]
    rc, dc = r * _QCONJ, d * _QCONJ
    return _join(rc / n2, dc / n2 - 2.0 * dot_last(r, d)[..., None] * rc / (n2 * n2))


def _c(a):
    """``(a cos a - sin a) / a^3`` = ``sinc'(a)/a``, by its series near 0."""
    a2 = a * a
    small = a < 1e-2
    safe = np.where(small, 1.0, a)
    direct = (safe * np.cos(safe) - np.sin(safe)) / (safe * safe * safe)
    series = -1.0 / 3.0 + a2 / 30.0 - a2 * a2 / 840.0 + a2 * a2 * a2 / 45360.0
    return np.where(small, series, direct)


def dqexp(h) -> np.ndarray:
    """Exponential of dual quaternions in the dual-quaternion algebra.

    For pure ``h = phi + eps psi`` (``a = |phi|``): ``exp(h) = exp(phi) + eps Dexp_phi[psi]``
    with ``exp(phi) = (cos a, sinc(a) phi)`` and
    ``Dexp_phi[psi] = (-sinc(a) phi.psi, sinc(a) psi + c(a) (phi.psi) phi)``,
    ``c(a) = (a cos a - sin a)/a^3``. The scalar dual part ``s + eps s'`` of a general ``h``
    commutes and contributes the factor ``e^s (1 + eps s')``. Exact at ``a = 0``.

    Parameters
    ----------
    h : array_like, shape (..., 8)

    Returns
    -------
    ndarray, shape (..., 8)
        Unit dual quaternions when ``h`` is pure.
    """
    h = as_dual_quaternion(h, "h")
    phi, psi = h[..., 1:4], h[..., 5:8]
    a = norm3(phi)
    sa = sinc(a)
    pp = dot_last(phi, psi)
    out = np.empty(h.shape)
    out[..., 0] = np.cos(a)
    out[..., 1:4] = sa[..., None] * phi
    out[..., 4] = -sa * pp
    out[..., 5:8] = sa[..., None] * psi + (_c(a) * pp)[..., None] * phi
    s, s_d = h[..., 0:1], h[..., 4:5]
    if np.any(s != 0.0) or np.any(s_d != 0.0):
        es = np.exp(s)
        out[..., 4:] = es * (out[..., 4:] + s_d * out[..., :4])
        out[..., :4] = es * out[..., :4]
    return out


def _flip_to_shortest(dq):
    return np.where((qcanonical(dq[..., :4]) != dq[..., :4]).any(axis=-1)[..., None], -dq, dq)


def dqlog(dq, shortest: bool = False) -> np.ndarray:
    """Logarithm of unit dual quaternions in the dual-quaternion algebra (inverse of :func:`dqexp`).

    The result is the pure dual quaternion ``phi + eps psi`` (half the twist of the screw
    motion). With ``phi = log r`` (angle ``a = |phi|``, axis ``n``) the dual part inverts
    ``Dexp_phi``: ``psi = s n + (a/sin a) (d_v - (d_v . n) n)``,
    ``s = -d_w sin a + (d_v . n) cos a``; at ``a = 0``, ``psi = d_v``.

    Parameters
    ----------
    dq : array_like, shape (..., 8)
        Unit dual quaternions.
    shortest : bool
        If True use ``-dq`` where its primary part is the canonical one (rotation angle in
        ``[0, pi]``), so the result is the same for ``dq`` and ``-dq``.

    Returns
    -------
    ndarray, shape (..., 8)
        ``dqexp(dqlog(dq)) == dq`` (``== +-dq`` with ``shortest``).

    Notes
    -----
    ``r = -1`` (a rotation of 2 pi) is the one point where ``a/sin a`` is unbounded: there
    the axis is taken along ``d_v`` (the log is then exact); near it the screw axis runs
    far away, the dual part grows like ``1/sin a`` and the log is ill-conditioned (a float
    angle next to pi cannot carry ``sin a`` below about 1e-16). Within ``sin a < 1e-8`` the
    primary part is treated as -1, which bounds ``|dqexp(dqlog(dq)) - dq|`` by about 1e-8
    there. ``shortest=True`` never comes near this point.
    """
    dq = as_unit_dual_quaternion(dq)
    if shortest:
        dq = _flip_to_shortest(dq)
    r, d = dq[..., :4], dq[..., 4:]
    # For unit r: sin a = |r_v| and cos a = r_w exactly, with a = atan2(|r_v|, r_w) in [0, pi].
    sin_a = norm3(r[..., 1:])
    cos_a = r[..., 0]
    a = np.arctan2(sin_a, cos_a)
    dv = d[..., 1:]
    has_axis = sin_a > 0.0
    n = r[..., 1:] / np.where(has_axis, sin_a, 1.0)[..., None]
    # r == -1: any axis will do; take it along d_v. Within _SIN_FLOOR of it, the axis from r_v
    # would amplify rounding by 1/sin(a) beyond what a float angle next to pi can carry, so r
    # is treated as -1 there (a change of at most _SIN_FLOOR in r).
    at_minus_one = (sin_a < _SIN_FLOOR) & (cos_a < 0.0)
    has_axis = has_axis & ~at_minus_one
    if np.any(at_minus_one):
        dvn = norm3(dv)
        along = np.where((dvn > 0.0)[..., None], dv / np.where(dvn > 0.0, dvn, 1.0)[..., None], [1.0, 0.0, 0.0])
        n = np.where(at_minus_one[..., None], along, n)
    dvn_par = dot_last(dv, n)
    s = -d[..., 0] * sin_a + dvn_par * cos_a
    ratio = a / np.where(has_axis, sin_a, 1.0)
    # The part of d_v across the axis, as n x (d_v x n): exactly orthogonal to n even where
    # n carries rounding, so the 1/sin(a) gain near r = -1 cannot leak into the axial part.
    across = np.cross(n, np.cross(dv, n))
    psi = s[..., None] * n + ratio[..., None] * across
    psi = np.where((has_axis | at_minus_one)[..., None], psi, dv)
    phi = a[..., None] * n
    out = np.zeros(dq.shape)
    out[..., 1:4] = phi
    out[..., 5:8] = psi
    return out


def dqpow(dq, a, shortest: bool = False) -> np.ndarray:
    """Screw power ``dq^a = exp(a log dq)`` of unit dual quaternions.

    ``dqpow(dq, a) dqpow(dq, b) = dqpow(dq, a + b)``; ``dqpow(dq, 2) = dq dq``.

    Parameters
    ----------
    dq : array_like, shape (..., 8)
    a : float or array_like, shape (...)
    shortest : bool
        Follow the screw motion of rotation angle at most pi (see :func:`dqlog`).
    """
    a = as_array(a, "a", None)
    return dqexp(a[..., None] * dqlog(dq, shortest=shortest))


def dqlog_decoupled(dq, shortest: bool = False) -> np.ndarray:
    """Decoupled logarithm ``log r + eps t/2`` of unit dual quaternions (dqrobotics ``log``).

    Rotation and translation are treated separately: ``(0, (theta/2) n, 0, t/2)``. Its
    inverse is :func:`dqexp_decoupled`, not :func:`dqexp`.

    Parameters
    ----------
    dq : array_like, shape (..., 8)
    shortest : bool
        Rotation part taken the short way (angle in ``[0, pi]``).

    Returns
    -------
    ndarray, shape (..., 8)
    """
    q, t = pose_from_dq(dq)
    out = np.zeros(np.broadcast_shapes(q.shape[:-1], t.shape[:-1]) + (8,))
    out[..., 1:4] = qlog(q, shortest=shortest)[..., 1:]
    out[..., 5:8] = 0.5 * t
    return out


def dqexp_decoupled(h) -> np.ndarray:
    """Inverse of :func:`dqlog_decoupled`: ``exp(phi) + eps psi exp(phi)`` for pure ``h``.

    Parameters
    ----------
    h : array_like, shape (..., 8)
        Pure dual quaternion ``(0, phi, 0, psi)``.

    Raises
    ------
    InvalidInputError
        If a scalar part of ``h`` is nonzero.
    """
    h = as_dual_quaternion(h, "h")
    if np.any(np.abs(h[..., [0, 4]]) > 1e-12):
        raise InvalidInputError(
            "h must be a pure dual quaternion (scalar parts h[..., 0] and h[..., 4] zero); "
            "the decoupled exponential is only defined there"
        )
    r = qexp(h[..., :4] * np.array([0.0, 1.0, 1.0, 1.0]))
    psi = h[..., 4:] * np.array([0.0, 1.0, 1.0, 1.0])
    return _join(r, qmul(psi, r))


def dqpow_decoupled(dq, a, shortest: bool = False) -> np.ndarray:
    """Decoupled power: rotation ``r^a``, translation ``a t`` (dqrobotics ``pow``).

    Parameters
    ----------
    dq : array_like, shape (..., 8)
        Unit dual quaternions.
    a : float or array_like, shape (...)
    shortest : bool
        Rotation part taken the short way.
    """
    a = as_array(a, "a", None)
    return dqexp_decoupled(a[..., None] * dqlog_decoupled(dq, shortest=shortest))


def dqsqrt_screw(dq, shortest: bool = True) -> np.ndarray:
    """Screw square root: ``dqpow(dq, 1/2)``; ``dqmul(h, h) == dq`` (``+-dq`` if ``shortest``).

    The half-way pose along the screw motion. It lies at the midpoint of the translation
    only when the translation is parallel to the rotation axis (or the rotation is zero).
    """
    return dqpow(dq, 0.5, shortest=shortest)


def dqsqrt_decoupled(dq, shortest: bool = True) -> np.ndarray:
    """Decoupled square root: half the rotation (short way by default), exactly half the translation.

    This is the root that seed 000 eq. (26) needs: with ``s = q2* q1`` (pose of robot 1 in
    robot 2's frame), ``q2 dqsqrt_decoupled(s)`` has position ``(p1 + p2)/2`` and
    orientation ``q2 (q2* q1)^(1/2)``, half-way between the robots' orientations. Its square
    is not ``dq`` in general, so ``qc h`` is *not* robot 1. Invert with the same ``h``:
    ``q2 = qc h*``, ``q1 = qc h* qs`` (exact). The form printed under eq. (27),
    ``q1 = qc ((qs*)^(1/2))*``, agrees with it except at a relative half turn, where the
    short-way roots of ``qs`` and ``qs* = -qs`` coincide; see ``docs/derivations.md``.
    """
    return dqpow_decoupled(dq, 0.5, shortest=shortest)


def dq_from_pose(q, t) -> np.ndarray:
    """Unit dual quaternion ``q + eps 1/2 t q`` of a pose (seed 000 §3.3).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Unit quaternion of the orientation.
    t : array_like, shape (..., 3)
        Position of the frame's origin in the parent frame.

    Returns
    -------
    ndarray, shape (..., 8)
    """
    q = as_unit_quaternion(q)
    t = as_array(t, "t", 3)
    tq = np.zeros(t.shape[:-1] + (4,))
    tq[..., 1:] = t
    return _join(q, 0.5 * qmul(tq, q))


def pose_from_dq(dq):
    """Orientation and translation of unit dual quaternions: ``t = 2 D(dq) P(dq)*``.

    seed 000 §3.3 prints ``2 D(q) P(q)^T``; the transpose is the quaternion conjugate.

    Returns
    -------
    q : ndarray, shape (..., 4)
    t : ndarray, shape (..., 3)
    """
    dq = as_unit_dual_quaternion(dq)
    r = dq[..., :4]
    return r, 2.0 * qmul(dq[..., 4:], qconj(r))[..., 1:]


def dq_transform_point(dq, p) -> np.ndarray:
    """Apply the pose ``dq`` to points ``p``: ``R(q) p + t``.

    Parameters
    ----------
    dq : array_like, shape (..., 8)
    p : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    q, t = pose_from_dq(dq)
    return qrotate(q, as_array(p, "p", 3)) + t


def dqcanonical(dq) -> np.ndarray:
    """``dq`` or ``-dq``, whichever has the canonical primary part (see ``qcanonical``)."""
    return _flip_to_shortest(as_dual_quaternion(dq))


def dq_closest(dq, ref) -> np.ndarray:
    """``dq`` or ``-dq``, whichever primary part is closer to ``ref``'s (``r . r_ref >= 0``)."""
    dq = as_dual_quaternion(dq)
    ref = as_dual_quaternion(ref, "ref")
    return np.where((dot_last(dq[..., :4], ref[..., :4]) < 0.0)[..., None], -dq, dq)
