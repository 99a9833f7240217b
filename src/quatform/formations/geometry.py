"""Unchecked quaternion helpers for the formations layer (internal: shared by quatform's layers, not part of the user API).

The public algebra functions validate every argument; a formation validates its input once
at the entry point and then calls these, which only compute. Layout and products follow
``docs/conventions.md``: ``(..., 4)`` quaternions ``(w, x, y, z)``, Hamilton product.
"""

from __future__ import annotations

import numpy as np

from ..algebra import wrap_angle
from ..algebra.kernels import array_namespace as namespace
from ..algebra.kernels import as_floats
from ..algebra.kernels import common_namespace as _xp
from ..algebra.kernels import dot_last, qmul_components
from . import pair_kernels as kern

EX = np.array([1.0, 0.0, 0.0])
EZ = np.array([0.0, 0.0, 1.0])
_CONJ = np.array([1.0, -1.0, -1.0, -1.0])


def mul(q, p):
    """Hamilton product ``q p`` of broadcast ``(..., 4)`` arrays (any namespace)."""
    xp = _xp(q, p)
    return xp.stack(xp.broadcast_arrays(*qmul_components(*xp.moveaxis(q, -1, 0), *xp.moveaxis(p, -1, 0))),
                    axis=-1)


def conj(q):
    return q * _CONJ


def dot(a, b):
    return dot_last(a, b)


def norm(v):
    return namespace(v).sqrt(dot(v, v))


def q_yaw(theta):
    """Rotation by ``theta`` about ``z``: ``(cos theta/2, 0, 0, sin theta/2)``, shape ``(..., 4)``."""
    theta = as_floats(theta)
    return _pack(kern.qyaw(theta), theta.shape)


def q_pitch_y(angle):
    """Rotation by ``angle`` about ``y``: ``(cos angle/2, 0, sin angle/2, 0)``, shape ``(..., 4)`` (any namespace)."""
    angle = as_floats(angle)
    xp = _xp(angle)
    z = xp.zeros_like(angle)
    return xp.stack([xp.cos(0.5 * angle), z, xp.sin(0.5 * angle), z], axis=-1)


def yaw_of(q):
    """Yaw (z-y-x) of nonzero quaternions ``(..., 4)``; see :func:`pair_kernels.yaw_of`."""
    q = as_floats(q)
    return kern.yaw_of(tuple(_xp(q).moveaxis(q, -1, 0)))


def rotate(q, v):
    """``R(q) v`` for unit ``q`` (vector part of ``q v q*``)."""
    xp = _xp(q, v)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * xp.cross(u, v)
    return v + w * t + xp.cross(u, t)


def x_axis(q):
    """First column of ``R(q)`` for unit ``q``, shape ``(..., 3)``."""
    q = as_floats(q)
    return _pack(kern.x_axis(tuple(_xp(q).moveaxis(q, -1, 0))), q.shape[:-1])


def z_axis(q):
    """Third column of ``R(q)`` for unit ``q``, shape ``(..., 3)``."""
    q = as_floats(q)
    return _pack(kern.z_axis(tuple(_xp(q).moveaxis(q, -1, 0))), q.shape[:-1])


def concat(parts):
    """Concatenate ``(..., k_i)`` arrays along the last axis, broadcasting their batch axes (any namespace)."""
    xp = _xp(*parts)
    shape = np.broadcast_shapes(*(np.shape(p)[:-1] for p in parts))
    return xp.concatenate([xp.broadcast_to(p, shape + np.shape(p)[-1:]) for p in parts], axis=-1)


def _pack(comps, shape):
    xp = _xp(*comps)
    return xp.stack([xp.broadcast_to(x, shape) for x in comps], axis=-1)


def closest_sign(q, ref):
    """``q`` or ``-q``, whichever is nearer ``ref`` (``q . ref >= 0``)."""
    return _xp(q, ref).where((dot(q, ref) < 0.0)[..., None], -q, q)


def swing(a, b, fallback_axis):
    """Minimal rotation taking unit vector ``a`` to unit vector ``b``.

    ``(1 + a.b, a x b)`` normalised: the rotation about ``a x b`` by the angle between them.
    At ``b = -a`` the axis is undefined; ``fallback_axis`` (a unit vector orthogonal to
    ``a``) is used there, giving the half turn about it.
    """
    xp = _xp(a, b)
    c = 1.0 + dot(a, b)
    v = xp.cross(a, b)
    q = xp.concatenate([c[..., None], v], axis=-1)
    n = norm(q)
    anti = n < 1e-12
    if xp is not np or np.any(anti):  # on JAX both branches, selected
        half = xp.concatenate([xp.zeros(np.shape(c) + (1,)), xp.broadcast_to(fallback_axis, v.shape)], axis=-1)
        q = xp.where(anti[..., None], half, q)
        n = xp.where(anti, 1.0, n)
    return q / n[..., None]


wrap = wrap_angle  # the algebra layer's rule, under the short name this layer's kernels use


def unwrap_near(a, ref):
    """``a + 2 pi k`` nearest ``ref``."""
    return ref + wrap(a - ref)
