"""Dual-quaternion team of N robots: seed 000 §3.3 (eqs. (26)-(27)) for any number and mix of robots.

Formations layer. Robot ``i`` is the unit dual quaternion ``qhat_i = q_i + eps 1/2 p_i q_i``
(seed 000 §3.3) of its orientation ``q_i`` (``q_yaw(theta_i)`` for ``xy_yaw`` / ``xyz_yaw``
robots, its own quaternion for ``pose`` robots, 1 for ``xyz`` robots) and its position
``p_i`` (a planar robot's ``z`` is 0). The formation's pose is ``qhat_c = pose(q_c, x_c)``:
the centroid ``x_c`` and a *mean rotation* ``q_c``, the N-robot form of the decoupled root
of eq. (26) (``docs/derivations.md``, "The dual-quaternion team"):

* robots with a yaw and no ``pose`` robot: ``q_c = q_yaw(mean of the robots' real yaws)``
  (for two robots the half-way yaw ``(theta_1 + theta_2)/2`` of the pair);
* a layout with ``pose`` robots: the orientation of its first ``pose`` robot (no symmetric
  mean of orientations is continuous: see the derivations);
* only ``xyz`` robots: the identity.

Two shapes:

* ``shape="frame"`` (default): ``qhat_ci = qhat_c* qhat_i``, each
  robot's pose in the formation frame; ``c = (qhat_c, qhat_c1, ..., qhat_cN)``. The inverse
  is ``qhat_i = qhat_c qhat_ci``: no root, no branch, so **every block's sign means
  nothing** (all law groups ``pose``) and ``inverse(forward(r)) = r`` always.
* ``shape="relative"``: seed 000's pair (§3.3, eqs. (26)-(27)), two ``xyz_yaw`` robots,
  ``c = (qhat_c, qhat_s)``. ``qhat_s = qhat_2* qhat_1`` is robot 1's pose in robot 2's frame,
  ``qhat_c = qhat_2 h`` the cluster frame, ``h`` the *decoupled* square root of ``qhat_s``
  (half the relative rotation, half the relative translation), so that ``qhat_c`` sits at
  the robots' midpoint with the half-way yaw. In closed form on the real yaws: ``qhat_c =
  pose(q_yaw((theta_1 + theta_2) / 2), (p_1 + p_2) / 2)``, ``qhat_s = pose(q_yaw(theta_1 -
  theta_2), R_z(-theta_2)(p_1 - p_2))``. The half-way yaw of two yaws is only defined mod pi;
  the description takes the branch of the robots' continuous yaws and records it in the
  **sign of** ``qhat_s`` (``h^2 = +qhat_s``): ``(+-qhat_c, qhat_s)`` and ``(+-qhat_c k,
  -qhat_s)`` (``k`` the half turn about the cluster's z axis) are one formation, and
  ``(qhat_c, -qhat_s)`` is that formation turned half a turn (the robots swapped), so
  ``inverse(forward(r)) = r`` without a hint (law group ``relative-pose``;
  ``docs/derivations.md``, "The two-robot formations and controllers (seed 000)").
  :class:`DualQuaternionPair` is this description with seed 000's Euclidean chart. For N >= 3
  robots one relative state would be the state of N formations turned by ``4 pi j / N`` about
  the centroid (the signs fix ``sum_k theta_sk`` only mod 4 pi), so a zero error would not
  mean the robots are at the reference: the relative shape is the pair's only.

The relative shape's maps are seed 000's closed forms on components (:func:`dq_forward`,
:func:`dq_inverse_jvp`): Python floats for one formation (a controller's real-time path,
:attr:`component_kernels`), NumPy or JAX arrays for a batch, one formula each.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..algebra.angles import TIE_TURNS
from ..algebra.kernels import array_namespace
from ..algebra.validate import as_array, as_unit_dual_quaternion
from ..errors import DegenerateInputError, InvalidInputError, UnreachableError
from . import geometry as g
from . import pair_kernels as kern
from . import special_sets as sp
from .base import MIN_SEPARATION_M, Formation, Preset, Variable
from .euclidean_team import EUCLIDEAN_VARIABLES, EuclideanPair
from .layout import POINT_KINDS, RobotLayout
from .quaternion_team import TILT_TOL, QuaternionPair
from .special_sets import SpecialSet
from .team_chart import (
    LawGroup,
    TeamChart,
    check_template,
    default_template,
    team_compose,
    team_layout,
    team_positions,
)

__all__ = ["CHARTS", "SHAPES", "DualQuaternionTeam", "DualQuaternionPair"]

#: The two shape definitions (module docstring).
SHAPES = ("frame", "relative")
#: The operator's charts: ``team`` (:class:`~.team_chart.TeamChart`), ``pair`` (seed 000's
#: Euclidean variables, two ``xyz_yaw`` robots with ``shape="relative"`` only).
CHARTS = ("team", "pair")

_TWO_PI = 2.0 * math.pi
_THREE_HALF_PI = 1.5 * math.pi
_KZ = np.array([0.0, 0.0, 0.0, 1.0])
_ONE = np.array([1.0, 0.0, 0.0, 0.0])
_DQ_CONJ = np.array([1.0, -1.0, -1.0, -1.0, 1.0, -1.0, -1.0, -1.0])
_QCONJ = _DQ_CONJ[:4]
_EZ = np.array([0.0, 0.0, 1.0])


# -- (dual) quaternion products on (..., k) arrays as two matmuls -----------------------------------
# The bilinear tensors of geometry.mul (Hamilton) and pair_kernels.dqmul, read off the unit
# vectors once: the products stay those functions' formulas; ``a @ T`` then ``b @ (..)`` is two
# NumPy calls whatever the batch (the component kernels cost about 30).
_E4, _E8 = np.eye(4), np.eye(8)
_QT = g.mul(_E4[:, None, :], _E4[None, :, :])  # (4, 4, 4): e_i e_j
_QT16 = _QT.reshape(4, 16)
_PT16 = _QT[1:].reshape(3, 16)  # (0, p) q: the pure quaternion's rows
_DT64 = kern.pack(kern.dqmul(tuple(_E8[:, None, :].transpose(2, 0, 1)), tuple(_E8[None, :, :].transpose(2, 0, 1)))
                  ).reshape(8, 64)


def _qm(a, b):
    """Hamilton product ``a b`` of ``(..., 4)`` arrays (geometry.mul's tensor)."""
    return (b[..., None, :] @ (a @ _QT16).reshape(a.shape[:-1] + (4, 4)))[..., 0, :]


def _pm(p, q):
    """``(0, p) q`` for ``p (..., 3)``, ``q (..., 4)``."""
    return (q[..., None, :] @ (p @ _PT16).reshape(p.shape[:-1] + (4, 4)))[..., 0, :]


def _dqmul(a, b):
    """Dual-quaternion product ``a b`` of ``(..., 8)`` arrays (pair_kernels.dqmul's tensor)."""
    return (b[..., None, :] @ (a @ _DT64).reshape(a.shape[:-1] + (8, 8)))[..., 0, :]


def _q_yaw(theta):
    """``(cos theta/2, 0, 0, sin theta/2)`` (geometry.q_yaw) in four NumPy calls, ``(..., 4)``."""
    xp = array_namespace(theta)
    if xp is not np:  # the same entries, stacked
        h = 0.5 * theta
        z = xp.zeros_like(h)
        return xp.stack([xp.cos(h), z, z, xp.sin(h)], axis=-1)
    h = 0.5 * np.asarray(theta, dtype=float)
    q = np.zeros(h.shape + (4,))
    q[..., 0] = np.cos(h)
    q[..., 3] = np.sin(h)
    return q


def _conj(q):
    return q * _QCONJ


def _pose(q, p):
    """``q + eps 1/2 p q`` (seed 000 §3.3), ``(..., 8)``; linear in ``q`` (not normalised)."""
    xp = array_namespace(q)
    return xp.concatenate(xp.broadcast_arrays(q, 0.5 * _pm(p, q)), axis=-1)


def _pose_rate(q, p, qd, pd):
    """Rate of :func:`_pose` along ``(qd, pd)``: ``(qd, 1/2 (pd q + p qd))``."""
    return np.concatenate(np.broadcast_arrays(qd, 0.5 * (_pm(pd, q) + _pm(p, qd))), axis=-1)


def _translation(dq):
    """``t = 2 vec(d r*) / |r|^2`` (seed 000 §3.3's ``2 D P*``, scale-free in ``r``), ``(..., 3)``."""
    r = dq[..., :4]
    return 2.0 * _qm(dq[..., 4:], _conj(r))[..., 1:] / array_namespace(dq).sum(r * r, axis=-1, keepdims=True)


def _yaw_and_translation_rates(dq, dqd):
    """Yaw rate and translation rate of the pose ``dq`` moving at ``dqd``.

    ``theta' = 2 (r' r*)_z / |r|^2`` (the z component of the world angular velocity; exact
    for a yaw, the projection of any other rate; the pair's rule, :func:`_pose_rates`) and
    ``t' = (2 vec(d' r* + d r'*) - 2 (r . r') t) / |r|^2``, the derivative of
    :func:`_translation` along any rate.
    """
    r, d, rd, dd = dq[..., :4], dq[..., 4:], dqd[..., :4], dqd[..., 4:]
    rc = _conj(r)
    w = _qm(rd, rc)
    m = _qm(dd, rc) + _qm(d, _conj(rd))
    xp = array_namespace(dqd)
    n2 = xp.sum(r * r, axis=-1, keepdims=True)
    t = 2.0 * _qm(d, rc)[..., 1:] / n2
    td = (2.0 * m[..., 1:] - 2.0 * xp.sum(r * rd, axis=-1, keepdims=True) * t) / n2
    return 2.0 * w[..., 3] / n2[..., 0], td


def _rot_z(theta, v, inverse=False):
    """``R_z(theta) v`` (or ``R_z(-theta) v``) for ``theta (...)``, ``v (..., 3)``."""
    c, s = np.cos(theta), np.sin(theta)
    if inverse:
        s = -s
    return np.stack(np.broadcast_arrays(c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1], v[..., 2]),
                    axis=-1)


def _wind(a, t):
    """``a`` moved by whole turns to within pi of ``t`` (``a - t`` in ``[-pi, pi)``; Formation.align's rule)."""
    return a + _TWO_PI * array_namespace(a).floor((t - a) / _TWO_PI + 0.5)


def _join(C, S):
    """``(..., 8)`` and ``(..., M, 8)`` blocks, broadcast, as one ``(..., 8 (M + 1))`` state."""
    shape = np.broadcast_shapes(C.shape[:-1], S.shape[:-2])
    xp = array_namespace(S)
    return xp.concatenate([xp.broadcast_to(C, shape + (8,)),
                           xp.broadcast_to(S, shape + S.shape[-2:]).reshape(shape + (-1,))], axis=-1)


def _dq_variables(prefix):
    return tuple(Variable(f"{prefix}_{p}{c}", "1", "quaternion") for p in "rd" for c in "wxyz")


# -- seed 000's pair (shape="relative"): closed forms on components ---------------------------------
# Components are Python floats (one formation: a controller's real-time path) or broadcastable
# arrays of any namespace (a batch; JAX under jax.jit), one formula for all (pair_kernels'
# component algebra).

def dq_forward(r, qch=None, stage=None):
    """Eqs. (26)-(27) in closed form on the branch of the given (real) yaws (16 components).

    ``qhat_c``: yaw ``(th1 + th2)/2`` at the midpoint; ``qhat_s``: yaw ``th1 - th2`` at
    ``R_z(-th2)(p1 - p2)``. ``qch`` (the rotation part of a hint's ``qhat_c``) sets the sign
    of ``qhat_c``, which means nothing. The sign of ``qhat_s`` is the branch of the
    half-way yaw and is never flipped: ``(qhat_c, -qhat_s)`` is the formation turned half a
    turn (``docs/derivations.md``, "The two-robot formations and controllers (seed 000)").
    ``stage`` (optional, a compiled loop's hold, as
    :func:`~.quaternion_team.quat_forward`'s) maps the yaws' cosines and sines to equal ones
    computed once.
    """
    x1, y1, z1, t1, x2, y2, z2, t2 = r
    L = kern.lib(t2)
    ha, hb = kern.qyaw(0.5 * (t1 + t2)), kern.qyaw(t1 - t2)
    c2, s2 = L.cos(t2), L.sin(t2)
    if stage is not None:
        ca, sa, cb, sb, c2, s2 = stage((ha[0], ha[3], hb[0], hb[3], c2, s2))
        ha, hb = (ca, ha[1], ha[2], sa), (cb, hb[1], hb[2], sb)
    qc = kern.pose(ha, (0.5 * (x1 + x2), 0.5 * (y1 + y2), 0.5 * (z1 + z2)))
    dx, dy, dz = x1 - x2, y1 - y2, z1 - z2
    qs = kern.pose(hb, (c2 * dx + s2 * dy, -s2 * dx + c2 * dy, dz))
    if qch is not None:
        qc = kern.neg_if(kern.qdot(qc[:4], qch) < 0.0, qc)
    return qc + qs


def dq_yaws(c):
    """Real yaws ``(theta_1, theta_2)`` that :func:`dq_forward` maps to the state ``c``.

    ``theta_c = 2 atan2(qc_z, qc_w)`` (mod 4 pi: the sign of ``qhat_c``) and
    ``theta_s / 2 = atan2(qs_z, qs_w)`` (mod 2 pi: the sign of ``qhat_s``);
    ``theta_1,2 = theta_c +- theta_s / 2``, the inverse of ``qhat_c = q_yaw((th1 + th2)/2)``,
    ``qhat_s = q_yaw(th1 - th2)``. Exact for yaw rotations; the yaw part of any other.
    """
    th_c = 2.0 * kern.atan2(c[3], c[0])
    half_s = kern.atan2(c[11], c[8])
    return th_c + half_s, th_c - half_s


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
    fl = math.floor if flt else kern.lib(r[3], t1).floor
    a1 = r[3] + _TWO_PI * fl((t1 - r[3]) / _TWO_PI + 0.5 + TIE_TURNS)  # a half turn's tie: the rule's way
    a2 = r[7] + _TWO_PI * fl((t2 - r[7]) / _TWO_PI + 0.5 + TIE_TURNS)
    rel = (a1 - t1) - (a2 - t2)
    if flt:
        a1 -= _TWO_PI if rel > _THREE_HALF_PI else (-_TWO_PI if rel < -_THREE_HALF_PI else 0.0)
    else:
        a1 = a1 - _TWO_PI * ((rel > _THREE_HALF_PI) * 1.0 - (rel < -_THREE_HALF_PI) * 1.0)
    return (r[0], r[1], r[2], a1, r[4], r[5], r[6], a2)


def _pose_rates(q, qd):
    """Yaw rate and translation rate of a unit pose ``q`` moving at ``qd``.

    ``theta_dot = 2 (r_dot r*)_z`` (the z component of the world angular velocity; exact
    for a yaw, the projection of any other rate) and ``t_dot = 2 vec(d_dot r* + d r_dot*)``.
    """
    r, d, rd, dd = q[:4], q[4:], qd[:4], qd[4:]
    w = kern.qmul(*rd, *kern.qconj(r))
    m = kern.qadd(kern.qmul(*dd, *kern.qconj(r)), kern.qmul(*d, *kern.qconj(rd)))
    return 2.0 * w[3], (2.0 * m[1], 2.0 * m[2], 2.0 * m[3])


def dq_inverse_jvp(c, cd, r):
    """Robot rates ``d INVKIN(c) [cd]`` of eqs. (26)-(27) on the branch of the robots ``r``.

    On the description's manifold (both dual quaternions a yaw and a translation) the
    inverse kinematics reads ``theta_1,2 = theta_c +- theta_s/2``,
    ``p_1,2 = x_c +- 1/2 R_z(theta_2) t_s``; its derivative along ``cd`` is this. Only
    ``theta_2`` is taken from ``r``: it fixes the square-root branch. Rates off the
    manifold are projected (yaw rate = z component of the angular velocity).
    """
    thc_d, xc_d = _pose_rates(c[:8], cd[:8])
    ths_d, ts_d = _pose_rates(c[8:], cd[8:])
    ts = kern.translation(c[8:])
    L = kern.lib(r[7])
    c2, s2 = L.cos(r[7]), L.sin(r[7])
    th1_d, th2_d = thc_d + 0.5 * ths_d, thc_d - 0.5 * ths_d
    ax, ay = c2 * ts[0] - s2 * ts[1], s2 * ts[0] + c2 * ts[1]  # R_z(theta_2) t_s = p1 - p2
    vx = 0.5 * (c2 * ts_d[0] - s2 * ts_d[1] - th2_d * ay)  # half of d/dt (p1 - p2)
    vy = 0.5 * (s2 * ts_d[0] + c2 * ts_d[1] + th2_d * ax)
    vz = 0.5 * ts_d[2]
    return (xc_d[0] + vx, xc_d[1] + vy, xc_d[2] + vz, th1_d,
            xc_d[0] - vx, xc_d[1] - vy, xc_d[2] - vz, th2_d)


class DualQuaternionTeam(Formation):
    """Seed 000 §3.3 for N robots: the formation's pose ``qhat_c`` and one unit dual quaternion
    per robot (module docstring).

    Parameters
    ----------
    n : int, optional
        Number of 4-DOF robots (``xyz_yaw``): ``DualQuaternionTeam(n)``, robot state
        ``(x1, y1, z1, theta1, ..., xn, yn, zn, thetan)``.
    layout : RobotLayout, optional
        Any mix of point kinds instead of ``n`` (``shape="relative"``: yaw robots only).
    template : array_like, shape (N, 3), optional
        The shape the team chart fits its attitude to when no ``near_e`` is given
        (:func:`~.team_chart.default_template` by default).
    shape : {"frame", "relative"}
        ``frame``: ``qhat_ci = qhat_c* qhat_i``; ``relative``: ``qhat_sk = qhat_N* qhat_k``.
    chart : {"team", "pair"}
        The operator's chart: the team chart (default) or, for two ``xyz_yaw`` robots with
        ``shape="relative"``, seed 000's Euclidean variables (:class:`DualQuaternionPair`).
    """

    name = "dual-quaternion-team"
    key = "dual-quaternion-team"
    rates_read_robots = True
    #: Formation.singularity_measure_arrays (robot_rate_arrays of the unit vectors) on any namespace.
    singularity_on_arrays = True
    team = True
    #: ``--controller dual-quaternion``.
    controller = "dual-quaternion"
    controller_order = 1
    #: Seed 000 Tables 1-2, eq. (28): ``K_dw``, the robots' yaws at its rate.
    gain_tables = {
        "table1": {"k_dw": [15.0, 15.0, 15.0], "k_theta": 15.0},
        "table2": {"k_dw": [0.5, 0.5, 0.5], "k_theta": 0.5},
    }

    @classmethod
    def examples(cls) -> dict:
        """The contract test's instances: a mix of point kinds."""
        return {cls.key: cls(layout=RobotLayout(("xyz_yaw", "xy_yaw", "pose", "xyz_yaw", "xyz")))}

    def __init__(self, n=None, *, layout=None, template=None, shape="frame", chart="team"):
        L = team_layout(n, layout, "DualQuaternionTeam")
        if shape not in SHAPES:
            raise InvalidInputError(f"DualQuaternionTeam: shape {shape!r} unknown; choose one of {', '.join(SHAPES)}")
        if chart not in CHARTS:
            raise InvalidInputError(f"DualQuaternionTeam: chart {chart!r} unknown; choose one of {', '.join(CHARTS)}")
        if shape == "relative" and L.n != 2:
            raise InvalidInputError(
                f"DualQuaternionTeam(shape='relative') is seed 000's pair (eq. (27)); for {L.n} robots one relative "
                f"state stands for {L.n} formations turned by 4 pi j / {L.n} about the centroid, so a zero error "
                "would not mean the robots are at the reference; use shape='frame' (each robot's pose in the "
                "formation frame)")
        if shape == "relative" and L.kinds != ("xyz_yaw", "xyz_yaw"):
            raise InvalidInputError(
                f"DualQuaternionTeam(shape='relative') is seed 000's pair of two xyz_yaw robots, the layout has "
                f"{', '.join(L.kinds)}; use shape='frame' for this layout")
        if chart == "pair" and (shape != "relative" or L.kinds != ("xyz_yaw", "xyz_yaw")):
            raise InvalidInputError(
                "DualQuaternionTeam: chart='pair' (seed 000's Euclidean variables) is for two xyz_yaw robots with "
                f"shape='relative', got {L.n} robots ({', '.join(L.kinds)}) with shape={shape!r}; use chart='team'")
        self.layout = L
        self.shape = shape
        #: The relative shape (seed 000's pair) runs a controller on its component kernels.
        self.component_kernels = shape == "relative"
        self.chart_kind = chart
        self.chart = TeamChart(L)
        self.template = default_template(L) if template is None else check_template(template, L.n)
        N = L.n
        self._n_blocks = N + 1 if shape == "frame" else N
        if shape == "frame":
            rest = sum((_dq_variables(f"qhat_c{lab}") for lab in L.labels), ())
        else:
            rest = _dq_variables("qhat_s")  # the pair's names (eqs. (26)-(27))
        self.variables = _dq_variables("qhat_c") + rest
        self.chart_variables = EUCLIDEAN_VARIABLES if chart == "pair" else self.chart.variables
        kinds = L.kinds
        self._yaw_robots = np.array([i for i, k in enumerate(kinds) if POINT_KINDS[k].yaw is not None], dtype=np.intp)
        self._pose_robots = np.array([i for i, k in enumerate(kinds) if k == "pose"], dtype=np.intp)
        self._planar_robots = np.array([i for i, k in enumerate(kinds) if k == "xy_yaw"], dtype=np.intp)
        #: how q_c is made: "pose" (first pose robot), "yaw" (mean real yaw), "none" (identity)
        self.mean_rule = "pose" if len(self._pose_robots) else ("yaw" if len(self._yaw_robots) else "none")

    def __repr__(self):
        return f"DualQuaternionTeam(layout={self.layout!r}, shape={self.shape!r}, chart={self.chart_kind!r})"

    # -- layout of the state ----------------------------------------------------------------
    @functools.cached_property
    def _block_index(self) -> np.ndarray:
        return np.arange(8 * self._n_blocks).reshape(self._n_blocks, 8)

    @functools.cached_property
    def sign_free(self) -> tuple:
        """``qhat_c`` always; the frame shape's ``qhat_ci`` too (the inverse is a product, signs
        cancel); the relative shape's ``qhat_sk`` are signed (their sign is the branch)."""
        if self.shape == "relative":
            return (slice(0, 8),)
        return tuple(slice(8 * k, 8 * k + 8) for k in range(self._n_blocks))

    @functools.cached_property
    def law_groups(self) -> tuple[LawGroup, ...]:
        """``frame``: one ``pose`` group of all N + 1 blocks (every sign free); ``relative``:
        ``qhat_c`` (``pose``) and the ``qhat_sk`` (``relative-pose``: driven to ``+qhat_sk_des``,
        the pair's branch rule)."""
        idx = self._block_index
        if self.shape == "frame":
            return (LawGroup("pose", idx),)
        return (LawGroup("pose", idx[:1]), LawGroup("relative-pose", idx[1:]))

    def _blocks(self, c):
        return c.reshape(c.shape[:-1] + (self._n_blocks, 8))

    def check_cluster_state(self, c, name="c"):
        """Finite ``(..., n_c)`` array of unit dual quaternions (each block), within the magnitude limit."""
        c = super().check_cluster_state(c, name)
        as_unit_dual_quaternion(self._blocks(c), f"{name} (its dual quaternions, block order {self._block_names})")
        return c

    @functools.cached_property
    def _block_names(self) -> str:
        names = [self.variables[8 * k].name[:-3] for k in range(self._n_blocks)]
        return ", ".join(names) if len(names) <= 4 else f"{names[0]}, {names[1]}, ..., {names[-1]}"

    # -- robots <-> dual quaternions ------------------------------------------------------------
    def _robot_rotations(self, r, yaws):
        """``(..., N, 4)`` rotations of the robots (yaws given as real numbers)."""
        L = self.layout
        shape = r.shape[:-1]
        if self.mean_rule == "yaw" and len(self._yaw_robots) == L.n:
            return _q_yaw(yaws)
        xp = array_namespace(r)
        if xp is not np:  # JAX: the yaw robots' rotations, the pose robots' and the identity of the rest, in order
            rest = np.setdiff1d(np.arange(L.n), np.concatenate([self._yaw_robots, self._pose_robots]))
            parts = [_q_yaw(yaws), r[..., L.orientation_index], xp.broadcast_to(_ONE, shape + (rest.size, 4))]
            order = np.concatenate([self._yaw_robots, self._pose_robots, rest])
            return xp.concatenate([xp.broadcast_to(a, shape + a.shape[-2:]) for a in parts], axis=-2)[
                ..., np.argsort(order), :]
        Q = np.broadcast_to(_ONE, shape + (L.n, 4)).copy()
        if len(self._yaw_robots):
            Q[..., self._yaw_robots, :] = _q_yaw(yaws)
        if len(self._pose_robots):
            Q[..., self._pose_robots, :] = L.orientations(r)
        return Q

    def _robot_rotation_rates(self, Q, r_dot):
        L = self.layout
        yd = L.yaws(r_dot)
        if len(self._yaw_robots) == L.n:
            return 0.5 * yd[..., None] * _qm(_KZ, Q)
        Qd = np.zeros(np.broadcast_shapes(Q.shape, r_dot.shape[:-1] + (L.n, 4)))
        if len(self._yaw_robots):
            Qd[..., self._yaw_robots, :] = 0.5 * yd[..., None] * _qm(_KZ, Q[..., self._yaw_robots, :])
        if len(self._pose_robots):
            Qd[..., self._pose_robots, :] = L.orientations(r_dot)
        return Qd

    def _desired_yaws(self, near_c):
        """Real yaws ``(..., N_yaw)`` of the yaw robots of the frame-shape state ``near_c``, and its
        formation yaw: the branch the measured yaws are wound onto."""
        B = self._blocks(near_c)
        rot = _qm(B[..., :1, :4], B[..., 1:, :4])[..., self._yaw_robots, :]  # q_c q_ci: the desired robots
        xp = array_namespace(near_c)
        if xp is not np:  # geometry.yaw_of's kernel on the namespace's axes
            return (kern.yaw_of(tuple(xp.moveaxis(rot, -1, 0))), kern.yaw_of(tuple(xp.moveaxis(B[..., 0, :4], -1, 0))))
        return g.yaw_of(rot), g.yaw_of(B[..., 0, :4])

    def _align(self, yaws, near_c):
        """The measured yaws moved by whole turns onto the frame-shape state ``near_c``'s
        branch, and the whole turns (of ``2 pi / N_yaw``) to add to their mean."""
        t, th_c = self._desired_yaws(near_c)
        a = _wind(yaws, t)
        n = t.shape[-1]
        xp = array_namespace(t)
        # the desired yaws' mean differs from the desired formation yaw by whole 2 pi / n (on the
        # description's set): take the lift of the measured yaws with the same offset
        k = xp.round((th_c - xp.mean(t, axis=-1)) * (n / _TWO_PI))
        return a, k * (_TWO_PI / n)

    def _mean_rotation(self, r, yaws, shift, hint):
        """``q_c (..., 4)``: module docstring; sign nearest ``hint`` where given."""
        L = self.layout
        xp = array_namespace(r)
        if xp is not np:  # the rules below without the layout's checks; geometry.closest_sign on the namespace
            if self.mean_rule == "yaw":
                q = _q_yaw(xp.mean(yaws, axis=-1) + shift)
            elif self.mean_rule == "pose":
                q = r[..., L.orientation_index[0]]
                q = q / xp.linalg.norm(q, axis=-1, keepdims=True)
            else:
                q = xp.broadcast_to(_ONE, r.shape[:-1] + (4,))
            return q if hint is None else xp.where((xp.sum(q * hint, axis=-1) < 0.0)[..., None], -q, q)
        if self.mean_rule == "yaw":
            q = _q_yaw(np.mean(yaws, axis=-1) + shift)
        elif self.mean_rule == "pose":
            q = L.orientations(r)[..., 0, :]
            q = q / np.linalg.norm(q, axis=-1, keepdims=True)
        else:
            q = np.broadcast_to(_ONE, r.shape[:-1] + (4,))
        return q if hint is None else g.closest_sign(q, hint)

    def _parts(self, r, near_c):
        """What :meth:`forward` and :meth:`cluster_rate` share: the (wound) yaws, positions,
        centroid and ``q_c``."""
        if near_c is not None:
            near_c = self.check_cluster_state(near_c, "near_c")
        return self._parts_arrays(r, near_c)

    def _parts_arrays(self, r, near_c):
        """:meth:`_parts` without the check of ``near_c``, on arrays of any namespace."""
        L = self.layout
        yaws = L.yaws(r)
        shift, hint = 0.0, None
        if near_c is not None:
            hint = near_c[..., :4]
            if yaws.shape[-1] and self.mean_rule == "yaw":
                yaws, shift = self._align(yaws, near_c)
        P = team_positions(L, r)
        xc = array_namespace(r).mean(P, axis=-2)
        return yaws, P, xc, self._mean_rotation(r, yaws, shift, hint)

    def forward(self, r, *, near_c=None):
        """``c`` of the robots ``r`` (module docstring), shape ``(..., n_c)``.

        Parameters
        ----------
        r : array_like, shape (..., n_r)
            Robot states, m and rad (yaws read as real numbers: their branch picks the mean
            yaw of the formation, and for ``relative`` the signs of ``qhat_sk``; every branch
            is the same formation).
        near_c : array_like, shape (..., n_c), optional
            A state to stay near (the controller's reference): the yaws of ``r`` are first
            moved by whole turns onto its branch (each within pi of the desired robot's;
            ``relative``: :func:`dq_align_yaws`, as the controller does), and
            ``qhat_c`` takes its sign. The result is the same formation as ``r`` whatever
            ``near_c``.
        """
        r = self.check_robot_state(r)
        self.check_apart(r)
        if near_c is not None:
            near_c = self.check_cluster_state(near_c, "near_c")
        return self.forward_arrays(r, near_c)

    def forward_arrays(self, r, near_c=None):
        """:meth:`forward` without its checks, on arrays of any namespace (NumPy; JAX under
        ``jax.jit``): the caller has checked ``r`` (finite, robots apart) and ``near_c``.
        ``relative``: seed 000 eqs. (26)-(27) in closed form (:func:`dq_forward`)."""
        if self.shape == "relative":
            if near_c is None:
                return kern.pack(dq_forward(kern.unpack(r)))
            h = kern.unpack(near_c)
            return kern.pack(dq_forward(dq_align_yaws(kern.unpack(r), *dq_yaws(h)), h[0:4]))
        yaws, P, xc, qc = self._parts_arrays(r, near_c)
        C = _pose(qc, xc)
        S = _dqmul((C * _DQ_CONJ)[..., None, :], _pose(self._robot_rotations(r, yaws), P))  # qhat_c* qhat_i
        return _join(C, S * self._block_signs(S, near_c))

    def _block_signs(self, S, near_c):
        """``+-1 (..., N, 1)``: each ``qhat_ci`` signed nearest ``near_c``'s (1 without it)."""
        if near_c is None:
            return 1.0
        xp = array_namespace(S)
        ref = (np.asarray(near_c, dtype=float) if xp is np else near_c)[..., 8:].reshape(near_c.shape[:-1] + (-1, 8))
        return xp.where(xp.sum(S[..., :4] * ref[..., :4], axis=-1, keepdims=True) < 0.0, -1.0, 1.0)

    def forward_components(self, rc, near_c, stage=None):
        """``relative``: eqs. (26)-(27) on components for a controller: the measured yaws moved
        by whole turns onto ``near_c``'s branch (each within pi of the desired robot's, the
        shape's relative-yaw error within 3 pi / 2; the sign of ``qhat_s`` is the branch),
        ``qhat_c`` with ``near_c``'s sign: ``(c, rc)`` with ``rc`` the wound robots
        (``stage``: :func:`dq_forward`'s)."""
        if not self.component_kernels:
            return super().forward_components(rc, near_c, stage)
        rc = dq_align_yaws(rc, *dq_yaws(near_c))
        kern.check_apart(rc, MIN_SEPARATION_M)
        return dq_forward(rc, near_c[0:4], stage=stage), rc

    def robot_rate_components(self, c, c_dot, rc):
        """``relative``: :meth:`robot_rate` on components (:func:`dq_inverse_jvp`)."""
        if not self.component_kernels:
            return super().robot_rate_components(c, c_dot, rc)
        return dq_inverse_jvp(c, c_dot, rc)

    def _check_yaws(self, rot, what, labels):
        """Refuse rotations ``rot (..., M, 4)`` (of robots with a yaw, named by ``labels``) that
        tilt: a 4-DOF or ground robot cannot roll or pitch (the pair's rule, ``TILT_TOL``)."""
        if not rot.shape[-2]:
            return
        q = rot / np.linalg.norm(rot, axis=-1, keepdims=True)
        tilt = np.linalg.norm(g.z_axis(q) - g.EZ, axis=-1)
        if np.any(tilt > TILT_TOL):
            k = int(np.argmax(np.max(tilt.reshape(-1, tilt.shape[-1]), axis=0)))
            raise UnreachableError(
                f"{what}: the rotation of {labels[k]} tilts by {float(np.max(tilt)):.3g} rad (limit {TILT_TOL:g}); "
                "a robot with a yaw only turns about z - build states with forward or from_chart")

    def inverse(self, c, *, near_r=None):
        """The robots of ``c``, shape ``(..., n_r)`` (yaws in ``(-pi, pi]`` without ``near_r``).

        ``frame``: ``qhat_i = qhat_c qhat_ci`` (no branch: ``inverse(forward(r)) = r`` with
        yaws mod 2 pi and ``pose`` quaternions as given). ``relative``: ``qhat_2 = qhat_c h*``,
        ``qhat_1 = qhat_c h* qhat_s`` with ``h`` the root of the signed ``qhat_s``
        (:meth:`_root`), so the result needs no branch choice. The form printed under seed 000
        eq. (27) fails at a relative half turn; this one is exact (``docs/derivations.md``,
        "The two-robot formations and controllers (seed 000)").

        Parameters
        ----------
        c : array_like, shape (..., n_c)
        near_r : array_like, shape (..., n_r), optional
            Robots whose yaws the result's are unwrapped near (within pi) and whose ``pose``
            quaternions' signs it takes; it does not change the formation.

        Raises
        ------
        UnreachableError
            A yaw robot's rotation tilts (a 4-DOF robot cannot roll or pitch).
        DegenerateInputError
            Two robots of ``c`` coincide (``relative``: the shape translates less than the
            robots' minimum separation).
        """
        c = self.check_cluster_state(c)
        L = self.layout
        if near_r is not None:
            near_r = self.check_robot_state(near_r, "near_r")
        if self.shape == "relative":
            r = self._relative_inverse(c, near_r)
        else:
            B = self._blocks(c)
            Qi = _dqmul(B[..., :1, :], B[..., 1:, :])  # qhat_i = qhat_c qhat_ci
            rot = Qi[..., :4]
            self._check_yaws(rot[..., self._yaw_robots, :], "c",
                             [f"robot {self.layout.display_names[i]}" for i in self._yaw_robots])
            P = _translation(Qi)
            if len(self._planar_robots):
                z = P[..., self._planar_robots, 2]
                if np.any(np.abs(z) > 1e-9 * np.maximum(1.0, np.max(np.abs(P), axis=(-2, -1)))[..., None]):
                    raise UnreachableError(f"c puts a ground robot (xy_yaw) at z = {float(np.max(np.abs(z))):.3g} m; "
                                           "a planar robot stays at z = 0 - build states with forward or from_chart")
            yaws = g.yaw_of(rot[..., self._yaw_robots, :]) if len(self._yaw_robots) else np.zeros(rot.shape[:-2] + (0,))
            q = rot[..., self._pose_robots, :]
            if len(self._pose_robots):
                q = q / np.linalg.norm(q, axis=-1, keepdims=True)
                if near_r is not None:
                    q = g.closest_sign(q, L.orientations(near_r))
            r = L.compose(P, yaws, q if len(self._pose_robots) else None)
            if near_r is not None and len(self._yaw_robots):
                r[..., list(L.yaw_indices)] = g.unwrap_near(r[..., list(L.yaw_indices)], near_r[..., list(L.yaw_indices)])
        self.check_apart(r, "the robots of c")
        return r

    @staticmethod
    def _root(qs):
        """The decoupled square root ``h`` of the signed shape ``qs``, shape ``(..., 8)``.

        ``h = (q_yaw(theta_s / 2), t_s / 2)`` with ``theta_s / 2 = atan2(qs_z, qs_w)``, so that
        ``h_p^2 = +qs_p`` (not ``-qs_p``): the root of ``qs`` and of ``-qs`` are half a turn
        apart, and which one is meant is the sign of ``qs`` (seed 000 eq. (26)). The yaw
        part of the rotation is used (the state is checked to be a yaw first).
        """
        rh = g.q_yaw(array_namespace(qs).arctan2(qs[..., 3], qs[..., 0]))
        t = 0.5 * kern.pack(kern.translation(kern.unpack(qs)))
        return kern.pack(kern.pose(kern.unpack(rh), kern.unpack(t)))

    def _relative_inverse(self, c, near_r):
        """Seed 000 eqs. (26)-(27) solved for the robots: ``qhat_2 = qhat_c h*``, ``qhat_1 =
        qhat_2 qhat_s`` (:meth:`inverse`)."""
        for s, what in ((slice(0, 8), "qhat_c"), (slice(8, 16), "qhat_s")):
            tilt = np.linalg.norm(g.z_axis(c[..., s][..., :4]) - g.EZ, axis=-1)
            if np.any(tilt > TILT_TOL):
                raise UnreachableError(
                    f"{what} tilts by {float(np.max(tilt)):.3g} rad; with 4-DOF robots its rotation "
                    "must be about z"
                )
        sep = np.linalg.norm(kern.pack(kern.translation(kern.unpack(c[..., 8:16]))), axis=-1)
        if np.any(sep < MIN_SEPARATION_M):
            raise DegenerateInputError(
                f"qhat_s translates by {float(np.min(sep)):.3g} m: the two robots would coincide; "
                f"the shape must separate them by at least {MIN_SEPARATION_M:g} m"
            )
        return self._relative_robots(c, near_r)

    def _relative_robots(self, c, near_r=None):
        """:meth:`_relative_inverse` without its checks, on arrays of any namespace."""
        xp = array_namespace(c)
        qs = kern.unpack(c[..., 8:16])
        dq2 = kern.dqmul(kern.unpack(c[..., 0:8]), kern.dqconj(kern.unpack(self._root(c[..., 8:16]))))  # qhat_c h*
        dq1 = kern.dqmul(dq2, qs)  # qhat_1 = qhat_2 qhat_s
        L = self.layout
        P = xp.stack([kern.pack(kern.translation(dq1)), kern.pack(kern.translation(dq2))], axis=-2)
        yaws = xp.stack([g.yaw_of(kern.pack(dq1[:4])), g.yaw_of(kern.pack(dq2[:4]))], axis=-1)
        if near_r is not None:
            yaws = g.unwrap_near(yaws, near_r[..., list(L.yaw_indices)])
        return L.compose(P, yaws) if xp is np else team_compose(L, P, yaws)

    # -- rate maps: directional derivatives on (..., N, 8) arrays, O(N) ------------------------------
    def cluster_rate(self, r, r_dot, *, near_c=None):
        """``c_dot = J r_dot`` at ``c = forward(r, near_c=near_c)``: the derivative of :meth:`forward`.

        ``x_c' = mean v_i``; ``q_c' = 1/2 theta_c' k q_c`` with ``theta_c' = mean theta_i'``
        (yaw rule), the derivative of the first pose robot's normalised quaternion (pose rule)
        or 0; a pose ``(q, p)`` moves at ``(q', 1/2 (p' q + p q'))``; ``qhat_ci' = qhat_c'* qhat_i +
        qhat_c* qhat_i'`` (frame); for ``relative`` :meth:`_relative_rate`.
        """
        r = self.check_robot_state(r)
        if self.shape == "relative":
            return self._relative_rate(r, as_array(r_dot, "r_dot", self.n_r), near_c)
        self.check_apart(r)
        yaws, P, xc, qc = self._parts(r, near_c)
        L = self.layout
        r_dot = as_array(r_dot, "r_dot", self.n_r)
        v = L.positions(r_dot)
        xcd = np.mean(v, axis=-2)
        yd = L.yaws(r_dot)
        if self.mean_rule == "yaw":
            qcd = 0.5 * np.mean(yd, axis=-1)[..., None] * _qm(_KZ, qc)
        elif self.mean_rule == "pose":
            q1 = L.orientations(r)[..., 0, :]
            n1 = np.linalg.norm(q1, axis=-1, keepdims=True)
            qh = q1 / n1
            q1d = L.orientations(r_dot)[..., 0, :]
            s = np.sum(qc * qh, axis=-1, keepdims=True)  # +-1: the sign forward gave q_c
            qcd = s * (q1d - qh * np.sum(qh * q1d, axis=-1, keepdims=True)) / n1
        else:
            qcd = np.zeros(np.broadcast_shapes(qc.shape, xcd.shape[:-1] + (4,)))
        Cd = _pose_rate(qc, xc, qcd, xcd)
        Q = self._robot_rotations(r, yaws)
        Qd = self._robot_rotation_rates(Q, r_dot)
        Qi, Qid = _pose(Q, P), _pose_rate(Q, P, Qd, v)
        Cc = (_pose(qc, xc) * _DQ_CONJ)[..., None, :]
        Sd = _dqmul((Cd * _DQ_CONJ)[..., None, :], Qi) + _dqmul(Cc, Qid)  # (qhat_c* qhat_i)'
        if near_c is not None:
            Sd = Sd * self._block_signs(_dqmul(Cc, Qi), near_c)
        return _join(Cd, Sd)

    def _relative_rate(self, r, r_dot, near_c):
        """``c_dot`` of the pair (``relative``): the derivative of the closed form of seed 000 eqs.
        (26)-(27), ``qhat_c = (yaw (th1+th2)/2, midpoint)``, ``qhat_s = (yaw th1-th2,
        R_z(-th2)(p1-p2))``.

        A pose ``(q_yaw(theta), t)`` moves at ``theta' d_angle + (0, 1/2 (0, t') q)`` with
        ``d_angle = (1/2 k q, 1/4 (0, t) k q)``; ``t_s' = R_z(-th2)(p1' - p2') - th2' (z x t_s)``.
        """
        c = self.forward(r, near_c=near_c)
        L = self.layout
        v, w = L.positions(r_dot), L.yaws(r_dot)
        parts = []
        for s in (slice(0, 8), slice(8, 16)):
            q = c[..., s]
            rot, t = q[..., :4], kern.pack(kern.translation(kern.unpack(np.asarray(q))))
            d_rot = 0.5 * g.mul(_KZ, rot)  # d rot / d angle
            d_angle = np.concatenate([d_rot, 0.5 * g.mul(_pure(t), d_rot)], axis=-1)
            # d (dual part) / d t = 1/2 (0, e_k) rot, k = x, y, z: (..., 4, 3)
            d_t = np.stack([0.5 * g.mul(_pure(e), rot) for e in np.eye(3)], axis=-1)
            if s.start == 0:
                angle_dot = 0.5 * (w[..., 0] + w[..., 1])
                dual = np.einsum("...ij,...j->...i", 0.5 * d_t, v[..., 0, :] + v[..., 1, :])
            else:
                # t_s' = R_z(-th2)(p1' - p2') - th2' (z x t_s)
                zx_t = np.stack([-t[..., 1], t[..., 0], np.zeros_like(t[..., 0])], axis=-1)
                angle_dot = w[..., 0] - w[..., 1]
                dual = (np.einsum("...ij,...j->...i", d_t @ _rot_z_T(L.yaws(r)[..., 1]), v[..., 0, :] - v[..., 1, :])
                        - w[..., 1, None] * np.einsum("...ij,...j->...i", d_t, zx_t))
            parts.append(angle_dot[..., None] * d_angle + g.concat([np.zeros(dual.shape[:-1] + (4,)), dual]))
        return g.concat(parts)

    def robot_rate(self, c, c_dot, *, r=None):
        """``r_dot`` of the cluster rate ``c_dot`` at ``c``: the derivative of :meth:`inverse`.

        ``frame``: ``qhat_i' = qhat_c' qhat_ci + qhat_c qhat_ci'``, then each robot's
        translation rate, yaw rate (z of the world angular velocity) or quaternion rate (of the
        quaternion ``qhat_c qhat_ci`` as ``c`` gives it: the robots' own sign when ``c =
        forward(r)``). O(N): a constant number of NumPy calls. ``relative``: the derivative of
        ``theta_1,2 = theta_c +- theta_s / 2``, ``p_1,2 = x_c +- 1/2 R_z(theta_2) t_s``
        (:func:`dq_inverse_jvp`) with ``theta_2`` from ``r``, the robots of ``c``
        (without ``r``: :func:`dq_yaws` of ``c``, the same angle mod 2 pi).
        """
        c = np.asarray(c, dtype=float)
        cd = as_array(c_dot, "c_dot", self.n_c)
        return self.robot_rate_arrays(c, cd, r=None if r is None else np.asarray(r, dtype=float))

    def robot_rate_arrays(self, c, cd, r=None):
        """:meth:`robot_rate` without its checks, on arrays of any namespace (NumPy; JAX under
        ``jax.jit``); ``relative``: ``r`` the robots of ``c`` (or None: their yaws from ``c``)."""
        if self.shape == "relative":
            cc = kern.unpack(c)
            rc = kern.unpack(r) if r is not None else (None,) * 7 + (dq_yaws(cc)[1],)  # only theta_2 is read
            return kern.pack(dq_inverse_jvp(cc, kern.unpack(cd), rc))
        B, Bd = self._blocks(c), self._blocks(cd)
        L = self.layout
        xp = array_namespace(cd)
        if xp is not np:
            Qi = _dqmul(B[..., :1, :], B[..., 1:, :])
            Qid = _dqmul(Bd[..., :1, :], B[..., 1:, :]) + _dqmul(B[..., :1, :], Bd[..., 1:, :])
            yd, V = _yaw_and_translation_rates(Qi, Qid)
            return team_compose(L, V, yd[..., self._yaw_robots], Qid[..., self._pose_robots, :4])
        C, Cd = B[..., :1, :], Bd[..., :1, :]
        S, Sd = B[..., 1:, :], Bd[..., 1:, :]
        Qi = _dqmul(C, S)
        Qid = _dqmul(Cd, S) + _dqmul(C, Sd)
        yd, V = _yaw_and_translation_rates(Qi, Qid)
        q = None
        if len(self._pose_robots):
            q = Qid[..., self._pose_robots, :4]
        return L.compose(V, yd[..., self._yaw_robots] if len(self._yaw_robots) else yd[..., :0], q)

    # -- the operator's chart -------------------------------------------------------------------------
    def to_chart(self, c, *, near_e=None, r=None):
        """The chart of the robots of ``c``: :meth:`TeamChart.from_robots` with this
        description's template where no ``near_e`` is given. ``r`` (else the robots of
        ``near_e``) only unwraps the yaws and signs the quaternions: ``c`` itself fixes the
        formation.

        ``chart="pair"``: seed 000's Euclidean variables of the robots of ``c``, read through
        the quaternion cluster frame. The dual quaternions carry no frame on the segment, so
        the branch of ``(beta_c, gamma_c)`` near the vertical is taken from ``near_e`` (the
        desired Euclidean state) through :meth:`QuaternionPair.to_chart`; without it, eqs.
        (1)-(8).
        """
        if self.chart_kind == "pair":
            if near_e is not None:
                near_e = EuclideanPair().check_cluster_state(near_e, "near_e")
            near = r if r is not None else (None if near_e is None else EuclideanPair().inverse(near_e))
            c = self.check_cluster_state(c)
            self._relative_inverse(c, None if near is None else self.check_robot_state(near, "near_r"))  # its checks
            return self.to_chart_arrays(c, near_e, None if near is None else np.asarray(near, dtype=float))
        near = r
        if near is None and near_e is not None:
            near = self.chart.robots(near_e)
        robots = self.inverse(c, near_r=near)
        return self.chart.from_robots(robots, near_e=near_e, template=self.template)

    def from_chart(self, e, e_dot=None):
        """``c`` (and ``c_dot``) of chart values ``e`` (and rates): the chart's robots
        (:meth:`TeamChart.robots`, :meth:`TeamChart.robot_rates`), then :meth:`forward` on their
        real yaws (so ``c`` is continuous in ``e``) and :meth:`cluster_rate`.

        ``chart="pair"``: closed form, continuous in ``e``: ``qhat_c`` = yaw ``beta + (phi1 +
        phi2)/2`` at the centroid, ``qhat_s`` = yaw ``phi1 - phi2`` at ``R_z(-theta_2)(p1 -
        p2)`` (seed 000 eqs. (1)-(8) and (26)-(27)); the rate through the dense matrices of
        :class:`EuclideanPair` and :meth:`jacobian` (the rounding the reference runs were
        recorded with)."""
        if self.chart_kind == "pair":
            return self._from_pair_chart(e, e_dot)
        e = self.chart.check(e, "e")
        r = self.chart.robots(e)
        rows = self.layout.orientation_index
        if len(rows):  # the chart's robot quaternions are directions: unit robots, tangent rates
            q = r[..., rows]
            n = np.linalg.norm(q, axis=-1, keepdims=True)
            r[..., rows] = q / n
        c = self.forward(r)
        if e_dot is None:
            return c
        r_dot = self.chart.robot_rates(e, e_dot)
        if len(rows):
            qh, qd = r[..., rows], r_dot[..., rows] / n
            r_dot[..., rows] = qd - qh * np.sum(qh * qd, axis=-1, keepdims=True)
        return c, self.cluster_rate(r, r_dot, near_c=c)

    @property
    def chart_on_arrays(self) -> bool:
        """The pair chart runs on any array namespace (:meth:`to_chart_arrays`); the team chart on NumPy."""
        return self.chart_kind == "pair"

    def to_chart_arrays(self, c, near_e=None, r=None):
        """:meth:`to_chart` of the pair chart on checked arrays of any namespace (NumPy, JAX):
        the robots of ``c`` (their yaws unwrapped near ``r``'s), eqs. (1)-(8) of them, or with
        ``near_e`` the quaternion pair's chart of them on ``near_e``'s branch."""
        if self.chart_kind != "pair":
            return super().to_chart_arrays(c, near_e, r)
        robots = self._relative_robots(c, r)
        if near_e is None:
            return EuclideanPair().forward_arrays(robots)
        qp = QuaternionPair()
        return qp.to_chart_arrays(qp.forward_arrays(robots, qp.from_chart_arrays(near_e)), near_e)

    def _from_pair_chart(self, e, e_dot):
        E = EuclideanPair()
        e = E.check_cluster_state(e, "e")
        r = E.inverse(e)
        beta = e[..., 3]
        qc = _pair_pose(g.q_yaw(beta + 0.5 * (e[..., 6] + e[..., 7])), e[..., 0:3])
        p = self.layout.positions(r)
        ts = np.einsum("...ij,...j->...i", _rot_z_T(self.layout.yaws(r)[..., 1]), p[..., 0, :] - p[..., 1, :])
        qs = _pair_pose(g.q_yaw(e[..., 6] - e[..., 7]), ts)
        c = np.concatenate([qc, qs], axis=-1)
        if e_dot is None:
            return c
        r_dot = np.einsum("...ij,...j->...i", E.inverse_jacobian_at(e), as_array(e_dot, "e_dot", 8))
        return c, np.einsum("...ij,...j->...i", self.jacobian(r, near_c=c), r_dot)

    # -- special sets -------------------------------------------------------------------------------
    def special_sets(self):
        """Where another description divides by zero, takes an undefined angle or meets ``q``
        versus ``-q``, and what this one does there (nothing special: every set is regular).

        Coincident robots are not a set of the description but bad input: :meth:`forward` and
        :meth:`inverse` raise DegenerateInputError naming the robots.
        """
        if self.shape == "relative":
            return sp.pair_sets("beta_c is undefined here; the dual quaternions are regular")
        L = self.layout
        sets = []
        gen = _TeamStates(L)
        if len(self._yaw_robots) >= 2:
            sets.append(SpecialSet(
                "half-turn-yaws", "two robots' yaws pi apart: the short root of eq. (26) jumps there; the mean of the "
                "real yaws (the decoupled root's branch) and every block are regular", gen.half_turn_yaws))
        if len(self._pose_robots) >= 2:
            sets.append(SpecialSet(
                "pose-half-turn", "two pose robots half a turn apart: a chordal mean of their orientations is "
                "undefined there (a tie); q_c is the first pose robot's orientation, regular", gen.pose_half_turn))
        if len(self._yaw_robots) or len(self._pose_robots):
            sets.append(SpecialSet(
                "q-vs-minus-q", "robot rotations with w = 0 (yaws pi, quaternions a half turn), where a canonical "
                "w >= 0 sign flips; the blocks' signs follow the robots' real yaws and quaternions, and the inverse "
                "is sign-free", gen.q_vs_minus_q))
        if len(self._yaw_robots):
            sets.append(SpecialSet(
                "wound-yaws", "yaws wound by up to 50 turns (read as real numbers by the mean yaw): another lift of "
                "the same formation, inverse(forward(r)) = r mod 2 pi", gen.wound_yaws))
        sets += [
            SpecialSet("vertical-axis", "robot 1 straight above robot 2 and the formation's plane vertical "
                       "(eq. (4)'s beta_c is 0/0, the chart's Euler reading is gimbal-locked); positions enter the "
                       "dual quaternions as translations only: regular", gen.vertical),
            SpecialSet("collinear", "every robot on one line (the chart's attitude fit is a tie, broken by its "
                       "hint); regular here", gen.collinear),
            SpecialSet("anti-x", "p1 - p2 along -x (the minimal rotation of eqs. (14)-(15) is 0/0); regular here",
                       gen.anti_x),
        ]
        return tuple(sets)


class DualQuaternionPair(Preset, DualQuaternionTeam):
    """Seed 000 §3.3: ``DualQuaternionTeam(2, shape="relative", chart="pair")``, the cluster frame
    ``qhat_c`` and the shape ``qhat_s`` of two 4-DOF robots (eqs. (26)-(27)), two unit dual
    quaternions, in seed 000's Euclidean chart; its controller is
    :class:`~quatform.control.quaternion.DualQuaternionController` (eq. (28))."""

    name = "dual-quaternion"
    key = "dual-quaternion"
    arguments = {"n": 2, "shape": "relative", "chart": "pair"}


def _pure(v):
    return np.concatenate([np.zeros(np.shape(v)[:-1] + (1,)), v], axis=-1)


def _pair_pose(q, t):
    """:func:`~.pair_kernels.pose` of arrays ``q (..., 4)``, ``t (..., 3)``."""
    return kern.pack(kern.pose(kern.unpack(np.asarray(q)), kern.unpack(np.asarray(t))))


def _rot_z_T(theta):
    """``R_z(theta)^T`` (``(..., 3, 3)``)."""
    c, s = np.cos(theta), np.sin(theta)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, s, z], -1), np.stack([-s, c, z], -1), np.stack([z, z, o], -1)], -2)


class _TeamStates:
    """Generators of robot states of a layout ``eps`` from the special sets (``eps = 0``: on it)."""

    def __init__(self, layout: RobotLayout):
        self.L = layout
        self.yaw_robots = [i for i, k in enumerate(layout.kinds) if POINT_KINDS[k].yaw is not None]
        self.pose_robots = [i for i, k in enumerate(layout.kinds) if k == "pose"]
        self.planar = np.array([k == "xy_yaw" for k in layout.kinds])

    def _ring(self, rng, n):
        """A ring of the robots (radius so that neighbours are >= 0.6 m apart), randomly placed and turned."""
        N = self.L.n
        R = max(1.0, 0.3 * N / math.pi * 1.2)
        a = 2.0 * math.pi * np.arange(N) / N + rng.uniform(-0.2, 0.2, (n, N))
        P = np.stack([R * np.cos(a), R * np.sin(a), rng.uniform(-0.3, 0.3, (n, N))], axis=-1)
        q = rng.normal(size=(n, 4))
        q = q / np.linalg.norm(q, axis=-1, keepdims=True)
        return rng.uniform(-2, 2, (n, 1, 3)) + g.rotate(q[:, None, :], P)

    def _compose(self, rng, P, yaws=None, quats=None):
        n = P.shape[0]
        P = np.array(P)
        if np.any(self.planar):  # a ground robot at z = 0, set apart in y from the others' projections
            P[:, self.planar, 1] += 5.0 + 0.7 * np.arange(np.count_nonzero(self.planar))
        if yaws is None:
            yaws = rng.uniform(-math.pi, math.pi, (n, len(self.yaw_robots)))
        if quats is None:
            quats = rng.normal(size=(n, len(self.pose_robots), 4))
            quats = quats / np.linalg.norm(quats, axis=-1, keepdims=True)
        return self.L.compose(P, yaws, quats if len(self.pose_robots) else None)

    def half_turn_yaws(self, rng, n, eps):
        y = rng.uniform(-math.pi, math.pi, (n, len(self.yaw_robots)))
        y[:, 1] = y[:, 0] - rng.choice([-1.0, 1.0], n) * (math.pi + eps)
        return self._compose(rng, self._ring(rng, n), y)

    def pose_half_turn(self, rng, n, eps):
        q = rng.normal(size=(n, len(self.pose_robots), 4))
        q = q / np.linalg.norm(q, axis=-1, keepdims=True)
        axis = rng.normal(size=(n, 3))
        axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
        h = 0.5 * (math.pi + eps)
        turn = np.concatenate([np.full((n, 1), math.cos(h)), math.sin(h) * axis], axis=-1)
        q[:, 1] = g.mul(q[:, 0], turn)
        return self._compose(rng, self._ring(rng, n), quats=q)

    def q_vs_minus_q(self, rng, n, eps):
        y = np.full((n, len(self.yaw_robots)), math.pi + eps) * rng.choice([-1.0, 1.0], (n, len(self.yaw_robots)))
        v = rng.normal(size=(n, len(self.pose_robots), 3))
        v = v / np.linalg.norm(v, axis=-1, keepdims=True)
        h = 0.5 * (math.pi + eps)
        q = np.concatenate([np.full(v.shape[:-1] + (1,), math.cos(h)), math.sin(h) * v], axis=-1)
        return self._compose(rng, self._ring(rng, n), y, q)

    def wound_yaws(self, rng, n, eps):
        y = rng.uniform(-math.pi, math.pi, (n, len(self.yaw_robots)))
        y = y + _TWO_PI * rng.integers(-50, 51, y.shape) + eps
        return self._compose(rng, self._ring(rng, n), y)

    def vertical(self, rng, n, eps):
        N = self.L.n
        a = 2.0 * math.pi * np.arange(N) / N
        u = np.stack([np.sin(a) * 1.2, np.zeros(N), np.cos(a) * 1.2], axis=-1)  # robot 1 on top; the x-z plane
        u[1] = (0.0, 0.0, -1.2) if N > 2 else u[1]  # robot 2 straight below robot 1
        if N > 2:
            u[2:] = np.stack([np.sin(a[2:] * 0.5 + 0.3) * 1.2, np.zeros(N - 2), np.cos(a[2:] * 0.5 + 0.3) * 0.9], -1)
        tilt = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(eps), -math.sin(eps)], [0.0, math.sin(eps), math.cos(eps)]])
        spin = rng.uniform(-math.pi, math.pi, n)
        P = _rot_z(spin[:, None], u @ tilt.T)
        return self._compose(rng, rng.uniform(-2, 2, (n, 1, 3)) + P)

    def collinear(self, rng, n, eps):
        N = self.L.n
        u = rng.normal(size=(n, 1, 3))
        u = u / np.linalg.norm(u, axis=-1, keepdims=True)
        off = rng.normal(size=(n, N, 3))
        off = off - np.sum(off * u, axis=-1, keepdims=True) * u
        s = (np.arange(N) - 0.5 * (N - 1)) * 0.7
        return self._compose(rng, rng.uniform(-2, 2, (n, 1, 3)) + s[None, :, None] * u + eps * off)

    def anti_x(self, rng, n, eps):
        P = self._ring(rng, n)
        d = P[:, 0] - P[:, 1]
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        psi = rng.uniform(-math.pi, math.pi, n)
        target = np.stack([-np.cos(eps) + 0.0 * psi, math.sin(eps) * np.cos(psi), math.sin(eps) * np.sin(psi)], -1)
        q = g.swing(d, target, np.array([0.0, 0.0, 1.0]))
        xc = P.mean(axis=1, keepdims=True)
        return self._compose(rng, xc + g.rotate(q[:, None, :], P - xc))
