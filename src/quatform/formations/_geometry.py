"""Unchecked quaternion helpers for the formations layer (private).

The public algebra functions validate every argument; a formation validates its input once
at the entry point and then calls these, which only compute. Layout and products follow
``docs/conventions.md``: ``(..., 4)`` quaternions ``(w, x, y, z)``, Hamilton product.
"""

from __future__ import annotations

import numpy as np

from ..algebra._kernels import qmul_components

EX = np.array([1.0, 0.0, 0.0])
EZ = np.array([0.0, 0.0, 1.0])
_CONJ = np.array([1.0, -1.0, -1.0, -1.0])


def mul(q, p):
    """Hamilton product ``q p`` of broadcast ``(..., 4)`` arrays."""
    return np.stack(qmul_components(*np.moveaxis(q, -1, 0), *np.moveaxis(p, -1, 0)), axis=-1)


def conj(q):
    return q * _CONJ


def dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def norm(v):
    return np.sqrt(dot(v, v))


def q_yaw(theta):
    """Rotation by ``theta`` about ``z``: ``(cos theta/2, 0, 0, sin theta/2)``, shape ``(..., 4)``."""
    theta = np.asarray(theta, dtype=float)
    q = np.zeros(theta.shape + (4,))
    q[..., 0] = np.cos(0.5 * theta)
    q[..., 3] = np.sin(0.5 * theta)
    return q


def q_pitch_y(angle):
    """Rotation by ``angle`` about ``y``."""
    angle = np.asarray(angle, dtype=float)
    q = np.zeros(angle.shape + (4,))
    q[..., 0] = np.cos(0.5 * angle)
    q[..., 2] = np.sin(0.5 * angle)
    return q


def yaw_of(q):
    """Yaw (z-y-x convention) of any nonzero quaternion; degree-2 homogeneous, so scale-free.

    ``atan2(2 (w z + x y), w^2 + x^2 - y^2 - z^2)``; for a pure yaw ``(cos a/2, 0, 0, sin a/2)``
    it is ``a`` wrapped to ``(-pi, pi]``. Undefined only at pitch +-90 deg, which a 4-DOF
    robot's orientation never reaches.
    """
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.arctan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def d_yaw_of(q):
    """Gradient of :func:`yaw_of` with respect to ``(w, x, y, z)``, shape ``(..., 4)``."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    n = 2.0 * (w * z + x * y)
    d = w * w + x * x - y * y - z * z
    s = n * n + d * d
    dn = np.stack([2 * z, 2 * y, 2 * x, 2 * w], axis=-1)
    dd = np.stack([2 * w, 2 * x, -2 * y, -2 * z], axis=-1)
    return (d[..., None] * dn - n[..., None] * dd) / s[..., None]


def rotate(q, v):
    """``R(q) v`` for unit ``q`` (vector part of ``q v q*``)."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def x_axis(q):
    """First column of ``R(q)`` for unit ``q``: ``q (0, 1, 0, 0) q*``."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)], axis=-1)


def z_axis(q):
    """Third column of ``R(q)`` for unit ``q``."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=-1)


def closest_sign(q, ref):
    """``q`` or ``-q``, whichever is nearer ``ref`` (``q . ref >= 0``)."""
    return np.where((dot(q, ref) < 0.0)[..., None], -q, q)


def swing(a, b, fallback_axis):
    """Minimal rotation taking unit vector ``a`` to unit vector ``b``.

    ``(1 + a.b, a x b)`` normalised: the rotation about ``a x b`` by the angle between them.
    At ``b = -a`` the axis is undefined; ``fallback_axis`` (a unit vector orthogonal to
    ``a``) is used there, giving the half turn about it.
    """
    c = 1.0 + dot(a, b)
    v = np.cross(a, b)
    q = np.concatenate([c[..., None], v], axis=-1)
    n = norm(q)
    anti = n < 1e-12
    if np.any(anti):
        half = np.concatenate([np.zeros(np.shape(c) + (1,)), np.broadcast_to(fallback_axis, v.shape)], axis=-1)
        q = np.where(anti[..., None], half, q)
        n = np.where(anti, 1.0, n)
    return q / n[..., None]


def wrap(a):
    """Angles wrapped to ``[-pi, pi)``."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def unwrap_near(a, ref):
    """``a + 2 pi k`` nearest ``ref``."""
    return ref + wrap(a - ref)
