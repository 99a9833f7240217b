"""Component algebra of quaternions and dual quaternions (internal: shared by quatform's layers, not part of the user API).

Each kernel takes and returns tuples of components. The components are either Python
floats (one formation: the fast path, no NumPy call overhead) or broadcastable arrays
(a batch) of NumPy or of any array namespace with NumPy's functions (JAX arrays under
``jax.jit``: :func:`~quatform.algebra.kernels.namespace`); the same code serves all, so each
formula is written once. A test on values (a branch, a refusal) is taken only where the
values are concrete (:func:`~quatform.algebra.kernels.concrete`); on traced arrays both
branches are computed and selected. Seed 000's closed forms of the two-robot descriptions
are written on this algebra in the team descriptions' modules
(:func:`~.quaternion_team.quat_forward`, :func:`~.dual_quaternion_team.dq_forward` and their
rates); the laws and the UGV-UAV description use it too.
"""

from __future__ import annotations

import math

import numpy as np

from ..algebra.kernels import concrete, namespace
from ..algebra.kernels import qmul_components as qmul
from ..errors import DegenerateInputError


def lib(*xs):
    """``math`` for floats, ``numpy`` for NumPy arrays, the arrays' namespace otherwise (that of
    the first operand that is not a float)."""
    return namespace(next((x for x in xs if not isinstance(x, float)), xs[0]))


def atan2(y, x):
    """``atan2`` of floats or arrays (any namespace)."""
    return math.atan2(y, x) if isinstance(y, float) and isinstance(x, float) else lib(y, x).arctan2(y, x)


def any_true(mask) -> bool:
    """Whether a concrete mask holds a True; True for a traced one (both branches are then taken)."""
    if isinstance(mask, (bool, np.bool_)):
        return bool(mask)
    return bool(np.any(mask)) if concrete(mask) else True


def select(mask, a, b):
    """``a`` where ``mask`` else ``b``, for floats or arrays (component tuples)."""
    if isinstance(mask, (bool, np.bool_)):
        return a if mask else b
    where = lib(mask).where
    return tuple(where(mask, x, y) for x, y in zip(a, b, strict=True))


def neg_if(mask, a):
    if isinstance(mask, (bool, np.bool_)):
        return tuple(-x for x in a) if mask else a
    s = lib(mask).where(mask, -1.0, 1.0)
    return tuple(s * x for x in a)


def qconj(a):
    return (a[0], -a[1], -a[2], -a[3])


def qdot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]


def qadd(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3])


def qscale(s, a):
    return tuple([s * x for x in a])


def qyaw(theta):
    """``(cos theta/2, 0, 0, sin theta/2)``."""
    L = lib(theta)
    h = 0.5 * theta
    return (L.cos(h), 0.0 * theta, 0.0 * theta, L.sin(h))


def yaw_of(q):
    """z-y-x yaw of any nonzero quaternion, scale-free: ``atan2(2(wz + xy), w^2 + x^2 - y^2 - z^2)``."""
    w, x, y, z = q
    n = 2.0 * (w * z + x * y)
    d = w * w + x * x - y * y - z * z
    return atan2(n, d)


def yaw_rate(q, qd):
    """Directional derivative of :func:`yaw_of` at ``q`` along ``qd``."""
    w, x, y, z = q
    a, b, c, e = qd
    n = 2.0 * (w * z + x * y)
    d = w * w + x * x - y * y - z * z
    dn = 2.0 * (a * z + w * e + b * y + x * c)
    dd = 2.0 * (w * a + x * b - y * c - z * e)
    return (d * dn - n * dd) / (n * n + d * d)


def x_axis(q):
    w, x, y, z = q
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y))


def z_axis(q):
    w, x, y, z = q
    return (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y))


# -- dual quaternions ------------------------------------------------------------------------

def dqmul(a, b):
    a0, a1, a2, a3, a4, a5, a6, a7 = a
    b0, b1, b2, b3, b4, b5, b6, b7 = b
    p = qmul(a0, a1, a2, a3, b4, b5, b6, b7)
    q = qmul(a4, a5, a6, a7, b0, b1, b2, b3)
    return qmul(a0, a1, a2, a3, b0, b1, b2, b3) + (p[0] + q[0], p[1] + q[1], p[2] + q[2], p[3] + q[3])


def dqadd(a, b):
    return tuple([x + y for x, y in zip(a, b)])


def dqconj(a):
    return qconj(a[:4]) + qconj(a[4:])


def pose(q, p):
    """Unit dual quaternion ``q + eps 1/2 p q`` of orientation ``q`` and position ``p``."""
    return tuple(q) + qscale(0.5, qmul(0.0, p[0], p[1], p[2], *q))


def translation(dq):
    m = qmul(*dq[4:], *qconj(dq[:4]))
    return (2.0 * m[1], 2.0 * m[2], 2.0 * m[3])


# -- packing --------------------------------------------------------------------------------

def unpack(a):
    """Components of ``(..., k)`` array ``a``: floats for 1-D NumPy input, array views otherwise
    (of any namespace)."""
    if not isinstance(a, np.ndarray):
        return tuple(a[..., i] for i in range(a.shape[-1]))
    return tuple(a.tolist()) if a.ndim == 1 else tuple(np.moveaxis(a, -1, 0))


def pack(comps, axis=-1):
    """Stack components (floats or arrays of one namespace) into one array along ``axis``;
    arrays pass through."""
    if not isinstance(comps, (tuple, list)):
        return comps
    if isinstance(comps[0], float) and isinstance(comps[-1], float):
        try:
            return np.array(comps, dtype=float)
        except (TypeError, ValueError):
            pass
    xp = next((lib(x) for x in comps if not isinstance(x, float)), np)
    return xp.stack(xp.broadcast_arrays(*comps), axis=axis)


def jacobian_from_jvp(jvp, c, n_c, *extra):
    """The matrix of ``jvp(c, .)`` (shape ``(..., n_out, n_c)``) by its action on the unit vectors."""
    cc = tuple(np.asarray(x)[..., None] for x in unpack(np.asarray(c)))
    ex = tuple(tuple(np.asarray(x)[..., None] for x in e) for e in extra)
    eye = np.eye(n_c)
    cols = jvp(cc, tuple(eye[k] for k in range(n_c)), *ex)
    return pack(cols, axis=-2)


def check_apart(r, min_m):
    """Raise DegenerateInputError if the two robots of the state components ``r`` (floats or
    arrays within the magnitude limit, so the squares are finite) are within ``min_m``."""
    d2 = (r[0] - r[4]) ** 2 + (r[1] - r[5]) ** 2 + (r[2] - r[6]) ** 2
    close = d2 <= min_m * min_m
    if not concrete(close):  # traced: the loop that traced it marks the worlds whose robots coincide
        return
    if close if isinstance(close, bool) else np.any(close):
        raise DegenerateInputError(
            f"measured robots coincide (separation {float(np.min(np.sqrt(d2))):.3g} m); a two-robot "
            "formation is undefined there - stop the robots and separate them"
        )
