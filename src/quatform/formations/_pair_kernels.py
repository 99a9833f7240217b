"""Component kernels of the two-robot quaternion and dual-quaternion descriptions (private).

Each kernel takes and returns tuples of components. The components are either Python
floats (one formation: the fast path, no NumPy call overhead) or broadcastable arrays
(a batch); the same code serves both, so each formula is written once. Formulas cite
seed 000; ``docs/derivations.md`` explains the departures from the printed forms.
"""

from __future__ import annotations

import math

import numpy as np

from ..algebra._kernels import qmul_components as qmul

_EPS_ANTI = 1e-12


def lib(x):
    """``math`` for floats, ``numpy`` for arrays."""
    return math if isinstance(x, float) else np


def select(mask, a, b):
    """``a`` where ``mask`` else ``b``, for floats or arrays (component tuples)."""
    if isinstance(mask, (bool, np.bool_)):
        return a if mask else b
    return tuple(np.where(mask, x, y) for x, y in zip(a, b, strict=True))


def neg_if(mask, a):
    if isinstance(mask, (bool, np.bool_)):
        return tuple(-x for x in a) if mask else a
    s = np.where(mask, -1.0, 1.0)
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
    return math.atan2(n, d) if isinstance(n, float) else np.arctan2(n, d)


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


# -- quaternion pair, seed 000 eqs. (9)-(19) -----------------------------------------------

def quat_forward(r, qh, q1h=None, q2h=None):
    """Forward kinematics, eqs. (9)-(15), with the twist of ``q_c`` taken from ``qh``.

    ``qh = (1, 0, 0, 0)`` gives the seed's minimal rotation from ``i`` (eqs. (14)-(15));
    any other ``qh`` gives the point of the measured fibre nearest ``qh``. ``q1h``, ``q2h``
    (optional) set the signs of ``q_c1``, ``q_c2``. Returns 16 components.
    """
    x1, y1, z1, t1, x2, y2, z2, t2 = r
    dx, dy, dz = x1 - x2, y1 - y2, z1 - z2
    D = (dx * dx + dy * dy + dz * dz) ** 0.5
    ux, uy, uz = dx / D, dy / D, dz / D
    ax, ay, az = x_axis(qh)
    # minimal rotation taking the hint's x axis to the segment: (1 + a.u, a x u), normalised
    s = (1.0 + ax * ux + ay * uy + az * uz, ay * uz - az * uy, az * ux - ax * uz, ax * uy - ay * ux)
    n = qdot(s, s) ** 0.5
    anti = n < _EPS_ANTI
    if anti if isinstance(anti, bool) else np.any(anti):  # segment opposite the hint: half turn about the hint's z axis
        zx, zy, zz = z_axis(qh)
        s = select(anti, (0.0 * n, zx, zy, zz), s)
        n = select(anti, (1.0 + 0.0 * n,), (n,))[0]
    s = qscale(1.0 / n, s)
    qc = qmul(*s, *qh)
    qcc = qconj(qc)
    q1 = qmul(*qcc, *qyaw(t1))  # eqs. (12)-(13)
    q2 = qmul(*qcc, *qyaw(t2))
    if q1h is not None:
        q1 = neg_if(qdot(q1, q1h) < 0.0, q1)
        q2 = neg_if(qdot(q2, q2h) < 0.0, q2)
    return (0.5 * (x1 + x2), 0.5 * (y1 + y2), 0.5 * (z1 + z2), *qc, 0.5 * D, *q1, *q2)


def quat_inverse_jvp(c, cd):
    """Robot rates ``d INVKIN(c) [cd]`` of eqs. (16)-(19): the inverse Jacobian times ``cd``.

    ``x1 = x_c + d q_c i q_c*``; its rate is ``x_c' + d' u + 2 d vec(q_c' i q_c*)``;
    ``theta_i = yaw(q_c q_ci)``. Returns 8 components.
    """
    qc, d, q1, q2 = c[3:7], c[7], c[8:12], c[12:16]
    qcd, dd = cd[3:7], cd[7]
    ux, uy, uz = x_axis(qc)
    m = qmul(*qmul(*qcd, 0.0, 1.0, 0.0, 0.0), *qconj(qc))
    vx = dd * ux + 2.0 * d * m[1]
    vy = dd * uy + 2.0 * d * m[2]
    vz = dd * uz + 2.0 * d * m[3]
    out = []
    for qi_c, qi_cd, sign in ((q1, cd[8:12], 1.0), (q2, cd[12:16], -1.0)):
        qi = qmul(*qc, *qi_c)
        qid = qadd(qmul(*qcd, *qi_c), qmul(*qc, *qi_cd))
        out += [cd[0] + sign * vx, cd[1] + sign * vy, cd[2] + sign * vz, yaw_rate(qi, qid)]
    return tuple(out)


# -- dual-quaternion pair, seed 000 eqs. (26)-(27) -----------------------------------------

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


def dq_forward(r, qch=None, qsh=None):
    """Eqs. (26)-(27) in closed form on the branch of the continuous yaws (16 components).

    ``qhat_c``: yaw ``(th1 + th2)/2`` at the midpoint; ``qhat_s``: yaw ``th1 - th2`` at
    ``R_z(-th2)(p1 - p2)``. ``qch``, ``qsh`` (rotation parts of a hint) set the signs.
    """
    x1, y1, z1, t1, x2, y2, z2, t2 = r
    L = lib(t2)
    qc = pose(qyaw(0.5 * (t1 + t2)), (0.5 * (x1 + x2), 0.5 * (y1 + y2), 0.5 * (z1 + z2)))
    dx, dy, dz = x1 - x2, y1 - y2, z1 - z2
    c2, s2 = L.cos(t2), L.sin(t2)
    qs = pose(qyaw(t1 - t2), (c2 * dx + s2 * dy, -s2 * dx + c2 * dy, dz))
    if qch is not None:
        qc = neg_if(qdot(qc[:4], qch) < 0.0, qc)
        qs = neg_if(qdot(qs[:4], qsh) < 0.0, qs)
    return qc + qs


def dq_root_of_robots(r, qc):
    """The root ``h = qhat_2* qhat_c`` of eq. (26) that the robots ``r`` are on."""
    return dqmul(dqconj(pose(qyaw(r[7]), r[4:7])), qc)


def dq_inverse_jvp(c, cd, h):
    """Robot rates ``d INVKIN(c) [cd]`` on the branch of the root ``h`` (8 components).

    ``INVKIN``: ``qhat_2 = qhat_c h(qhat_s)*``, ``qhat_1 = qhat_2 qhat_s`` with the decoupled
    root ``h(qhat_s) = (n, 1/2 (d_s r_s*) n)``, ``n = (1 + sig r_s)/|1 + sig r_s|`` (times a
    half turn about z on the long branch), then ``p = 2 vec(d r*)``, ``theta = yaw(r)``.
    """
    qc, qs, qcd, qsd = c[:8], c[8:], cd[:8], cd[8:]
    rs, ds, rsd, dsd = qs[:4], qs[4:], qsd[:4], qsd[4:]
    rh = h[:4]
    sig = 1.0 - 2.0 * (rs[0] < 0.0)
    v = (1.0 + sig * rs[0], sig * rs[1], sig * rs[2], sig * rs[3])
    nv = qdot(v, v) ** 0.5
    n = qscale(1.0 / nv, v)
    long = abs(qdot(rh, n)) < 0.5
    n_long = qmul(*n, 0.0, 0.0, 0.0, 1.0)
    nb = select(long, n_long, n)
    s_h = 1.0 - 2.0 * (qdot(rh, nb) < 0.0)
    proj = qdot(n, rsd)
    nd = tuple(sig * (x - y * proj) / nv for x, y in zip(rsd, n, strict=True))
    rhd = qscale(s_h, select(long, qmul(*nd, 0.0, 0.0, 0.0, 1.0), nd))
    ts2 = qmul(*ds, *qconj(rs))
    ts2d = qadd(qmul(*dsd, *qconj(rs)), qmul(*ds, *qconj(rsd)))
    dhd = qscale(0.5, qadd(qmul(*ts2d, *rh), qmul(*ts2, *rhd)))
    hd = rhd + dhd
    hc = dqconj(h)
    q2 = dqmul(qc, hc)
    q2d = dqadd(dqmul(qcd, hc), dqmul(qc, dqconj(hd)))
    q1 = dqmul(q2, qs)
    q1d = dqadd(dqmul(q2d, qs), dqmul(q2, qsd))
    out = []
    for q, qd in ((q1, q1d), (q2, q2d)):
        m = qadd(qmul(*qd[4:], *qconj(q[:4])), qmul(*q[4:], *qconj(qd[:4])))
        out += [2.0 * m[1], 2.0 * m[2], 2.0 * m[3], yaw_rate(q[:4], qd[:4])]
    return tuple(out)


# -- packing --------------------------------------------------------------------------------

def unpack(a):
    """Components of ``(..., k)`` array ``a``: floats for 1-D input, array views otherwise."""
    return tuple(a.tolist()) if a.ndim == 1 else tuple(np.moveaxis(a, -1, 0))


def pack(comps, axis=-1):
    """Stack components (floats or arrays) into one array along ``axis``; arrays pass through."""
    if isinstance(comps, np.ndarray):
        return comps
    if isinstance(comps[0], float) and isinstance(comps[-1], float):
        try:
            return np.array(comps, dtype=float)
        except (TypeError, ValueError):
            pass
    return np.stack(np.broadcast_arrays(*comps), axis=axis)


def jacobian_from_jvp(jvp, c, n_c, *extra):
    """The matrix of ``jvp(c, .)`` (shape ``(..., n_out, n_c)``) by its action on the unit vectors."""
    cc = tuple(np.asarray(x)[..., None] for x in unpack(np.asarray(c)))
    ex = tuple(tuple(np.asarray(x)[..., None] for x in e) for e in extra)
    eye = np.eye(n_c)
    cols = jvp(cc, tuple(eye[k] for k in range(n_c)), *ex)
    return pack(cols, axis=-2)
