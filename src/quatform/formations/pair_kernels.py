"""Component kernels of the two-robot quaternion and dual-quaternion descriptions (internal: shared by quatform's layers, not part of the user API).

Each kernel takes and returns tuples of components. The components are either Python
floats (one formation: the fast path, no NumPy call overhead) or broadcastable arrays
(a batch) of NumPy or of any array namespace with NumPy's functions (JAX arrays under
``jax.jit``: :func:`~quatform.algebra.kernels.namespace`); the same code serves all, so each
formula is written once. A test on values (a branch, a refusal) is taken only where the
values are concrete (:func:`~quatform.algebra.kernels.concrete`); on traced arrays both
branches are computed and selected. Formulas cite
seed 000; ``docs/derivations.md`` explains the departures from the printed forms.
"""

from __future__ import annotations

import math

import numpy as np

from ..algebra.angles import TIE_TURNS
from ..algebra.kernels import concrete, namespace
from ..algebra.kernels import qmul_components as qmul
from ..errors import DegenerateInputError

_EPS_ANTI = 1e-12


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


# -- quaternion pair, seed 000 eqs. (9)-(19) -----------------------------------------------

def quat_forward(r, qh, q1h=None, q2h=None, stage=None):
    """Forward kinematics, eqs. (9)-(15), with the twist of ``q_c`` taken from ``qh``.

    ``qh = (1, 0, 0, 0)`` gives the seed's minimal rotation from ``i`` (eqs. (14)-(15));
    any other ``qh`` gives the point of the measured fibre nearest ``qh``. ``q1h``, ``q2h``
    (optional) set the signs of ``q_c1``, ``q_c2``. ``stage`` (optional, a compiled loop's
    hold: ``ClusterController.chain``) maps the robots' half-yaw cosines and sines to equal
    ones computed once (each output component's loop would recompute them). Returns 16
    components.
    """
    x1, y1, z1, t1, x2, y2, z2, t2 = r
    dx, dy, dz = x1 - x2, y1 - y2, z1 - z2
    D = (dx * dx + dy * dy + dz * dz) ** 0.5
    ux, uy, uz = dx / D, dy / D, dz / D
    ax, ay, az = x_axis(qh)
    # minimal rotation taking the hint's x axis to the segment: (1 + a.u, a x u), normalised;
    # for a.u < 0, 1 + a.u = |a x u|^2 / (1 - a.u) (no cancellation near the opposite direction)
    c = ax * ux + ay * uy + az * uz
    vx, vy, vz = ay * uz - az * uy, az * ux - ax * uz, ax * uy - ay * ux
    vv = vx * vx + vy * vy + vz * vz
    if isinstance(c, float):
        w = 1.0 + c if c >= 0.0 else vv / (1.0 - c)
    else:
        L = lib(c)
        w = L.where(c >= 0.0, 1.0 + c, vv / L.maximum(1.0 - c, 1.0))  # 1 - c >= 1 where used
    s = (w, vx, vy, vz)
    n = qdot(s, s) ** 0.5
    anti = n < _EPS_ANTI
    if any_true(anti):  # segment opposite the hint: half turn about the hint's z axis
        zx, zy, zz = z_axis(qh)
        s = select(anti, (0.0 * n, zx, zy, zz), s)
        n = select(anti, (1.0 + 0.0 * n,), (n,))[0]
    s = qscale(1.0 / n, s)
    qc = qmul(*s, *qh)
    qcc = qconj(qc)
    h1, h2 = qyaw(t1), qyaw(t2)
    if stage is not None:
        c1, s1, c2, s2 = stage((h1[0], h1[3], h2[0], h2[3]))
        h1, h2 = (c1, h1[1], h1[2], s1), (c2, h2[1], h2[2], s2)
    q1 = qmul(*qcc, *h1)  # eqs. (12)-(13)
    q2 = qmul(*qcc, *h2)
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


def dq_forward(r, qch=None, stage=None):
    """Eqs. (26)-(27) in closed form on the branch of the given (real) yaws (16 components).

    ``qhat_c``: yaw ``(th1 + th2)/2`` at the midpoint; ``qhat_s``: yaw ``th1 - th2`` at
    ``R_z(-th2)(p1 - p2)``. ``qch`` (the rotation part of a hint's ``qhat_c``) sets the sign
    of ``qhat_c``, which means nothing. The sign of ``qhat_s`` is the branch of the
    half-way yaw and is never flipped: ``(qhat_c, -qhat_s)`` is the formation turned half a
    turn (``docs/derivations.md``, "The two-robot formations and controllers (seed 000)"). ``stage`` (optional, a compiled
    loop's hold, as :func:`quat_forward`'s) maps the yaws' cosines and sines to equal ones
    computed once.
    """
    x1, y1, z1, t1, x2, y2, z2, t2 = r
    L = lib(t2)
    ha, hb = qyaw(0.5 * (t1 + t2)), qyaw(t1 - t2)
    c2, s2 = L.cos(t2), L.sin(t2)
    if stage is not None:
        ca, sa, cb, sb, c2, s2 = stage((ha[0], ha[3], hb[0], hb[3], c2, s2))
        ha, hb = (ca, ha[1], ha[2], sa), (cb, hb[1], hb[2], sb)
    qc = pose(ha, (0.5 * (x1 + x2), 0.5 * (y1 + y2), 0.5 * (z1 + z2)))
    dx, dy, dz = x1 - x2, y1 - y2, z1 - z2
    qs = pose(hb, (c2 * dx + s2 * dy, -s2 * dx + c2 * dy, dz))
    if qch is not None:
        qc = neg_if(qdot(qc[:4], qch) < 0.0, qc)
    return qc + qs


def dq_yaws(c):
    """Real yaws ``(theta_1, theta_2)`` that :func:`dq_forward` maps to the state ``c``.

    ``theta_c = 2 atan2(qc_z, qc_w)`` (mod 4 pi: the sign of ``qhat_c``) and
    ``theta_s / 2 = atan2(qs_z, qs_w)`` (mod 2 pi: the sign of ``qhat_s``);
    ``theta_1,2 = theta_c +- theta_s / 2``, the inverse of ``qhat_c = q_yaw((th1 + th2)/2)``,
    ``qhat_s = q_yaw(th1 - th2)``. Exact for yaw rotations; the yaw part of any other.
    """
    th_c = 2.0 * atan2(c[3], c[0])
    half_s = atan2(c[11], c[8])
    return th_c + half_s, th_c - half_s


_TWO_PI = 2.0 * math.pi
_THREE_HALF_PI = 1.5 * math.pi


def dq_align_yaws(r, t1, t2):
    """``r`` (8 components) with its yaws moved by whole turns onto the branch of the
    desired yaws ``t1``, ``t2`` (real numbers, :func:`dq_yaws` of the desired state).

    Each yaw goes to within pi of its desired one (``theta - t`` in ``(-pi, pi]``, the rule of
    :meth:`Formation.align`): the cluster's yaw error ``(a1 + a2)/2`` is then within pi and
    the shape's ``a1 - a2`` within 2 pi. Where the shape's exceeds ``3 pi / 2`` robot 1's yaw
    is taken a turn back (the other lift of the same formation): the shape law drives
    ``qhat_s`` to ``+qhat_s_des`` and has its unstable equilibrium at a shape error of
    ``2 pi`` (``qe_s = -1``), which this keeps at least ``pi / 2`` away
    (``docs/derivations.md``, "The two-robot formations and controllers (seed 000)").
    """
    flt = isinstance(r[3], float) and isinstance(t1, float)
    fl = math.floor if flt else lib(r[3], t1).floor
    a1 = r[3] + _TWO_PI * fl((t1 - r[3]) / _TWO_PI + 0.5 + TIE_TURNS)  # a half turn's tie: the rule's way
    a2 = r[7] + _TWO_PI * fl((t2 - r[7]) / _TWO_PI + 0.5 + TIE_TURNS)
    rel = (a1 - t1) - (a2 - t2)
    if flt:
        a1 -= _TWO_PI if rel > _THREE_HALF_PI else (-_TWO_PI if rel < -_THREE_HALF_PI else 0.0)
    else:
        a1 = a1 - _TWO_PI * ((rel > _THREE_HALF_PI) * 1.0 - (rel < -_THREE_HALF_PI) * 1.0)
    return (r[0], r[1], r[2], a1, r[4], r[5], r[6], a2)


def _yaw_and_translation_rates(q, qd):
    """Yaw rate and translation rate of a unit pose ``q`` moving at ``qd``.

    ``theta_dot = 2 (r_dot r*)_z`` (the z component of the world angular velocity; exact
    for a yaw, the projection of any other rate) and ``t_dot = 2 vec(d_dot r* + d r_dot*)``.
    """
    r, d, rd, dd = q[:4], q[4:], qd[:4], qd[4:]
    w = qmul(*rd, *qconj(r))
    m = qadd(qmul(*dd, *qconj(r)), qmul(*d, *qconj(rd)))
    return 2.0 * w[3], (2.0 * m[1], 2.0 * m[2], 2.0 * m[3])


def dq_inverse_jvp(c, cd, r):
    """Robot rates ``d INVKIN(c) [cd]`` of eqs. (26)-(27) on the branch of the robots ``r``.

    On the description's manifold (both dual quaternions a yaw and a translation) the
    inverse kinematics reads ``theta_1,2 = theta_c +- theta_s/2``,
    ``p_1,2 = x_c +- 1/2 R_z(theta_2) t_s``; its derivative along ``cd`` is this. Only
    ``theta_2`` is taken from ``r``: it fixes the square-root branch. Rates off the
    manifold are projected (yaw rate = z component of the angular velocity).
    """
    thc_d, xc_d = _yaw_and_translation_rates(c[:8], cd[:8])
    ths_d, ts_d = _yaw_and_translation_rates(c[8:], cd[8:])
    ts = translation(c[8:])
    L = lib(r[7])
    c2, s2 = L.cos(r[7]), L.sin(r[7])
    th1_d, th2_d = thc_d + 0.5 * ths_d, thc_d - 0.5 * ths_d
    ax, ay = c2 * ts[0] - s2 * ts[1], s2 * ts[0] + c2 * ts[1]  # R_z(theta_2) t_s = p1 - p2
    vx = 0.5 * (c2 * ts_d[0] - s2 * ts_d[1] - th2_d * ay)  # half of d/dt (p1 - p2)
    vy = 0.5 * (s2 * ts_d[0] + c2 * ts_d[1] + th2_d * ax)
    vz = 0.5 * ts_d[2]
    return (xc_d[0] + vx, xc_d[1] + vy, xc_d[2] + vz, th1_d,
            xc_d[0] - vx, xc_d[1] - vy, xc_d[2] - vz, th2_d)


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
