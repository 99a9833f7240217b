"""Quaternions: Hamilton product, conjugate, norm, log/exp/power, rotations, double cover.

Bottom of the algebra layer; depends only on NumPy and :mod:`quatform.errors`.

Layout: ``(..., 4)`` arrays ``(w, x, y, z)``; every function broadcasts over leading axes
and returns a new array. ``q`` and ``-q`` are the same rotation (the double cover): the
algebraic functions (``qlog``, ``qpow``, ``axis_angle_from_q``) keep the sign they are
given unless asked for ``shortest=True``; ``qcanonical``, ``q_closest`` and
``q_continuous`` choose a sign on purpose.
"""

from __future__ import annotations

import numpy as np

from ..errors import DegenerateInputError, NotARotationError
from . import kernels
from .validate import as_array, as_quaternion, as_unit_quaternion

__all__ = [
    "IDENTITY",
    "qmul",
    "qconj",
    "qinv",
    "qnorm",
    "qnormalize",
    "qexp",
    "qlog",
    "qpow",
    "qslerp",
    "qrotate",
    "q_from_axis_angle",
    "axis_angle_from_q",
    "matrix_from_q",
    "q_from_matrix",
    "qcanonical",
    "q_closest",
    "q_continuous",
    "q_angle",
    "q_angle_between",
]

#: The identity quaternion ``(1, 0, 0, 0)``.
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])

_CONJ = np.array([1.0, -1.0, -1.0, -1.0])


def dot_last(a, b):
    """Dot products over the last axis of two arrays ``(..., k)``: shape ``(...)``."""
    return np.einsum("...i,...i->...", a, b)


def norm3(v):
    """Euclidean norm over the last axis of ``(..., 3)`` without under- or overflow.

    ``sqrt(x^2 + y^2 + z^2)`` turns subnormal below ``|v| ~ 1e-154`` and loses relative
    accuracy there, which the ratios ``angle / |v|`` of the log maps would amplify.
    """
    return np.hypot(np.hypot(v[..., 0], v[..., 1]), v[..., 2])


def qmul(q, p) -> np.ndarray:
    """Hamilton product ``q p``.

    seed 001 eq. (2.18): ``q p = (q0 p0 - q.p, q0 p + p0 q + q x p)``.

    Parameters
    ----------
    q, p : array_like, shape (..., 4)
        Any quaternions (not necessarily unit); leading axes broadcast.

    Returns
    -------
    ndarray, shape (..., 4)
    """
    q = as_quaternion(q, "q")
    p = as_quaternion(p, "p")
    return kernels.run_blocked(kernels.qmul_components, (q, p), 4)


def qconj(q) -> np.ndarray:
    """Conjugate ``q* = (w, -x, -y, -z)`` (seed 001 eq. (2.15)). Shape (..., 4)."""
    return as_quaternion(q) * _CONJ


def qnorm(q) -> np.ndarray:
    """Euclidean norm ``||q|| = sqrt(q q*)`` (seed 001 eq. (2.19)). Shape (...)."""
    q = as_quaternion(q)
    return np.sqrt(dot_last(q, q))


def nonzero_norm(q, name, what="a zero quaternion", why="its direction is undefined - supply a nonzero quaternion"):
    """Norms of ``q`` ``(..., k)`` over the last axis, shape ``(...)``; DegenerateInputError naming the first zero."""
    n = np.sqrt(dot_last(q, q))
    if np.any(n == 0.0):
        raise DegenerateInputError(f"{name} has {what} at index {tuple(np.argwhere(n == 0.0)[0])}; {why}")
    return n


def qnormalize(q) -> np.ndarray:
    """Unit quaternion ``q / ||q||`` (seed 001 eq. (2.14)).

    Raises
    ------
    DegenerateInputError
        If some ``q`` is zero.
    """
    q = as_quaternion(q)
    return q / nonzero_norm(q, "q")[..., None]


def qinv(q) -> np.ndarray:
    """Inverse ``q^-1 = q* / ||q||^2``; equals ``qconj`` for unit quaternions.

    Raises
    ------
    DegenerateInputError
        If some ``q`` is zero.
    """
    q = as_quaternion(q)
    n = nonzero_norm(q, "q")
    return q * _CONJ / (n * n)[..., None]


def sinc(a):
    """``sin(a) / a`` with the limit 1 at 0 (elementwise, ``a`` in rad)."""
    return np.sinc(a / np.pi)


def qexp(q) -> np.ndarray:
    """Exponential of any quaternion: ``exp(w + v) = e^w (cos|v|, sin|v| v/|v|)``.

    seed 001 eqs. (2.28)-(2.29). Exact at ``v = 0`` (no division by ``|v|``).

    Parameters
    ----------
    q : array_like, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    q = as_quaternion(q)
    v = q[..., 1:]
    a = norm3(v)
    s = np.exp(q[..., 0])
    out = np.empty(np.broadcast_shapes(q.shape))
    out[..., 0] = s * np.cos(a)
    out[..., 1:] = (s * sinc(a))[..., None] * v
    return out


def _log_vector(q):
    """Vector part of the principal log of nonzero quaternions and their norm.

    Returns ``(angle/2) * axis`` with ``angle/2 = atan2(|v|, w)`` in ``[0, pi]``. At
    ``v = 0, w < 0`` (``q = -|q|``) the axis is undefined; the x axis is chosen so that
    ``exp(log q) = q`` still holds.
    """
    v = q[..., 1:]
    s = norm3(v)
    w = q[..., 0]
    half = np.arctan2(s, w)
    # The unit axis: v scaled by its largest component first (exact, into [-1, 1]), then
    # normalised, so a subnormal v (whose norm rounds to a multiple of 5e-324) still gives a
    # unit axis; where v = 0 the log's vector is 0.
    big = np.max(np.abs(v), axis=-1)
    u = v / np.where(big > 0.0, big, 1.0)[..., None]
    axis = u / np.where(big > 0.0, norm3(u), 1.0)[..., None]
    out = half[..., None] * axis
    neg_real = (s == 0.0) & (w < 0.0)
    if np.any(neg_real):
        out = np.array(out)
        out[neg_real] = [np.pi, 0.0, 0.0]
    return out, np.sqrt(s * s + w * w)


def qlog(q, shortest: bool = False) -> np.ndarray:
    """Principal logarithm ``log q = (ln||q||, (theta/2) n)`` of nonzero quaternions.

    seed 001 eqs. (2.26)-(2.27). ``theta/2 = atan2(|v|, w)`` lies in ``[0, pi]``, so
    ``qexp(qlog(q)) == q`` for every nonzero ``q``, sign included.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Nonzero quaternions.
    shortest : bool
        If True, take the log of ``qcanonical(q)`` instead: the rotation's own log, with
        ``theta`` in ``[0, pi]`` (the short way round). Then ``exp(log q) = +-q``.

    Returns
    -------
    ndarray, shape (..., 4)

    Notes
    -----
    At ``q = -1`` the axis is undefined; the x axis is returned (``exp`` still maps it back
    to ``-1``). With ``shortest=True`` this point maps to ``0`` instead.
    """
    q = as_quaternion(q)
    nonzero_norm(q, "q")
    if shortest:
        q = qcanonical(q)
    vec, n = _log_vector(q)
    out = np.empty(q.shape)
    out[..., 0] = np.log(n)
    out[..., 1:] = vec
    return out


def qpow(q, a, shortest: bool = False) -> np.ndarray:
    """Power ``q^a = exp(a log q)`` of nonzero quaternions.

    For unit ``q`` this rotates ``a`` times as far about the same axis;
    ``qpow(q, a) qpow(q, b) = qpow(q, a + b)`` holds for all real ``a, b`` because both
    factors are functions of the same ``log q`` and commute.

    Parameters
    ----------
    q : array_like, shape (..., 4)
    a : float or array_like, shape (...)
        Exponent(s), broadcast against the leading axes of ``q``.
    shortest : bool
        Use the short-way log (see :func:`qlog`): ``qpow(q, 0.5, shortest=True)`` is the
        half rotation of less than 90 degrees, the same for ``q`` and ``-q``.
    """
    a = as_array(a, "a", None)
    return qexp(a[..., None] * qlog(q, shortest=shortest))


def qslerp(q0, q1, t, shortest: bool = True) -> np.ndarray:
    """Spherical linear interpolation ``q0 (q0* q1)^t`` between unit quaternions.

    Parameters
    ----------
    q0, q1 : array_like, shape (..., 4)
        Unit quaternions.
    t : float or array_like, shape (...)
        Interpolation parameter; 0 gives ``q0``, 1 gives ``q1`` (up to sign if ``shortest``).
    shortest : bool
        Interpolate along the shorter arc of rotations (default).
    """
    q0 = as_unit_quaternion(q0, "q0")
    q1 = as_unit_quaternion(q1, "q1")
    return qmul(q0, qpow(qmul(qconj(q0), q1), t, shortest=shortest))


def qrotate(q, v) -> np.ndarray:
    """Rotate vectors: the vector part of ``q (0, v) q*`` for unit ``q``.

    seed 001 eq. (2.22); seed 000 eq. (16).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Unit quaternions (renormalised within tolerance, else NonUnitError).
    v : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    q = as_unit_quaternion(q)
    v = as_array(v, "v", 3)
    u = q[..., 1:]
    w = q[..., 0:1]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def q_from_axis_angle(axis, angle) -> np.ndarray:
    """Unit quaternion ``(cos(angle/2), sin(angle/2) n)`` with ``n = axis / ||axis||``.

    seed 001 eq. (2.14); seed 003 eqs. (1)-(4).

    Parameters
    ----------
    axis : array_like, shape (..., 3)
        Rotation axis; need not be unit, may be zero only where ``angle`` is 0.
    angle : float or array_like, shape (...)
        Rotation angle in radians (right-hand rule).
    """
    axis = as_array(axis, "axis", 3)
    angle = as_array(angle, "angle", None)
    n = np.sqrt(dot_last(axis, axis))
    bad = (n == 0.0) & (angle != 0.0)
    if np.any(bad):
        raise DegenerateInputError(
            "axis is zero where angle is nonzero; a rotation needs a nonzero axis"
        )
    unit = axis / np.where(n == 0.0, 1.0, n)[..., None]
    half = 0.5 * angle
    shape = np.broadcast_shapes(unit.shape[:-1], np.shape(half))
    out = np.empty(shape + (4,))
    out[..., 0] = np.cos(half)
    out[..., 1:] = np.sin(half)[..., None] * unit
    return out


#: Below this a vector's norm may have lost its relative precision (subnormal components).
_TINY_NORM = 1e-290


def axis_angle_from_q(q, shortest: bool = False):
    """Axis and angle of unit quaternions.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Unit quaternions.
    shortest : bool
        If False (default) the angle is ``2 atan2(|v|, w)`` in ``[0, 2 pi]`` and
        ``q_from_axis_angle`` of the result returns ``q`` itself. If True, the angle of
        ``qcanonical(q)`` in ``[0, pi]`` is returned.

    Returns
    -------
    axis : ndarray, shape (..., 3)
        Unit axis; ``(1, 0, 0)`` where the angle is 0 or ``2 pi`` (axis undefined).
    angle : ndarray, shape (...)
    """
    q = as_unit_quaternion(q)
    if shortest:
        q = qcanonical(q)
    v = q[..., 1:]
    s = norm3(v)
    angle = 2.0 * np.arctan2(s, q[..., 0])
    axis = np.where((s > 0.0)[..., None], v / np.where(s > 0.0, s, 1.0)[..., None], [1.0, 0.0, 0.0])
    tiny = (s > 0.0) & (s < _TINY_NORM)
    if np.any(tiny):  # subnormal |v|: its norm rounds (5e-324 * sqrt 3 is 5e-324); scale v first
        big = np.max(np.abs(v), axis=-1, keepdims=True)
        w = v / np.where(big > 0.0, big, 1.0)
        nw = norm3(w)  # 0 in the worlds that are not tiny (v = 0): those keep the axis above
        axis = np.where(tiny[..., None], w / np.where(tiny, nw, 1.0)[..., None], axis)
    return axis, angle


def matrix_from_q(q) -> np.ndarray:
    """Rotation matrix of unit quaternions, ``R v = q v q*``.

    seed 001 eq. (2.45): ``R = (w^2 - |u|^2) I + 2 u u^T + 2 w [u]x``.

    Parameters
    ----------
    q : array_like, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    q = as_unit_quaternion(q)
    w, x, y, z = (q[..., i] for i in range(4))
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def q_from_matrix(R, tol: float = 1e-6) -> np.ndarray:
    """Unit quaternion of rotation matrices, canonical sign (see :func:`qcanonical`).

    Shepperd's method: the largest of ``4w^2, 4x^2, 4y^2, 4z^2`` is taken from the diagonal,
    so no branch divides by a small number.

    Parameters
    ----------
    R : array_like, shape (..., 3, 3)
        Rotation matrices.
    tol : float
        Accepted ``max |R^T R - I|`` and ``|det R - 1|``.

    Raises
    ------
    NotARotationError
        If some ``R`` is not orthonormal with determinant +1 within ``tol``.
    """
    R = as_array(R, "R", (3, 3))
    err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-2, -1))
    det = np.linalg.det(R)
    bad = (err > tol) | (np.abs(det - 1.0) > tol)
    if np.any(bad):
        i = np.argwhere(np.atleast_1d(bad))[0]
        raise NotARotationError(
            f"R{'' if R.ndim == 2 else ' at index ' + str(tuple(int(k) for k in i))} is not a "
            f"rotation matrix: max|R^T R - I| = {np.atleast_1d(err)[tuple(i)]:.3g}, "
            f"det = {np.atleast_1d(det)[tuple(i)]:.6g} (tolerance {tol:g}); "
            "orthonormalise it (e.g. by SVD) and make det = +1"
        )
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    # Four candidate squared magnitudes (times 4).
    cand = np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], axis=-1)
    k = np.argmax(cand, axis=-1)
    big = 0.5 * np.sqrt(np.take_along_axis(cand, k[..., None], axis=-1)[..., 0])
    f = 0.25 / big
    s_w = (R[..., 2, 1] - R[..., 1, 2]) * f
    s_x = (R[..., 0, 2] - R[..., 2, 0]) * f
    s_y = (R[..., 1, 0] - R[..., 0, 1]) * f
    xy = (R[..., 0, 1] + R[..., 1, 0]) * f
    xz = (R[..., 0, 2] + R[..., 2, 0]) * f
    yz = (R[..., 1, 2] + R[..., 2, 1]) * f
    rows = np.stack(
        [
            np.stack([big, s_w, s_x, s_y], axis=-1),
            np.stack([s_w, big, xy, xz], axis=-1),
            np.stack([s_x, xy, big, yz], axis=-1),
            np.stack([s_y, xz, yz, big], axis=-1),
        ],
        axis=-2,
    )
    q = np.take_along_axis(rows, k[..., None, None], axis=-2)[..., 0, :]
    return qcanonical(q / np.sqrt(dot_last(q, q))[..., None])


def qcanonical(q) -> np.ndarray:
    """Canonical representative of ``+-q``: ``w > 0``, or at ``w = 0`` the first nonzero
    of ``(x, y, z)`` positive.

    Every rotation has exactly one canonical quaternion. No sign choice on the double cover
    can be continuous everywhere: near ``w = 0`` (rotations by ~pi) the canonical form
    jumps between ``q`` and ``-q``. Use :func:`q_continuous` or :func:`q_closest` where a
    signal must stay continuous.

    Parameters
    ----------
    q : array_like, shape (..., 4)
    """
    q = as_quaternion(q)
    # The sign of the first nonzero component in the order (w, x, y, z).
    nz = q != 0.0
    first = np.argmax(nz, axis=-1)
    lead = np.take_along_axis(q, first[..., None], axis=-1)
    return np.where(lead < 0.0, -q, q)


def q_closest(q, ref) -> np.ndarray:
    """Sign of ``q`` nearest to ``ref``: ``q`` or ``-q``, whichever has ``q . ref >= 0``.

    Parameters
    ----------
    q, ref : array_like, shape (..., 4)
    """
    q = as_quaternion(q)
    ref = as_quaternion(ref, "ref")
    return np.where((dot_last(q, ref) < 0.0)[..., None], -q, q)


def q_continuous(q, axis: int = 0) -> np.ndarray:
    """Choose signs along a sequence so consecutive quaternions have ``q_k . q_k+1 >= 0``.

    The quaternion analogue of :func:`numpy.unwrap`: the first element keeps its sign.

    Parameters
    ----------
    q : array_like, shape (..., 4)
        A sequence of quaternions along ``axis`` (which must not be the last axis).
    axis : int
        Time axis.
    """
    q = as_quaternion(q)
    ax = axis % q.ndim
    if ax == q.ndim - 1:
        raise ValueError("axis must index the sequence, not the quaternion components")
    qm = np.moveaxis(q, ax, 0)
    flips = np.sign(dot_last(qm[1:], qm[:-1]))
    flips[flips == 0] = 1.0
    signs = np.concatenate([np.ones((1,) + flips.shape[1:]), np.cumprod(flips, axis=0)])
    return np.moveaxis(qm * signs[..., None], 0, ax)


def q_angle(q) -> np.ndarray:
    """Rotation angle of unit quaternions in ``[0, pi]`` (sign of ``q`` irrelevant)."""
    q = as_unit_quaternion(q)
    return 2.0 * np.arctan2(norm3(q[..., 1:]), np.abs(q[..., 0]))


def q_angle_between(q1, q2) -> np.ndarray:
    """Angle in ``[0, pi]`` of the rotation taking orientation ``q1`` to ``q2``."""
    return q_angle(qmul(qconj(as_unit_quaternion(q1, "q1")), as_unit_quaternion(q2, "q2")))
