"""Dual-quaternion cluster space of two 4-DOF robots, seed 000 eqs. (26)-(27).

Formations layer. ``c = (qhat_c[8], qhat_s[8])``: ``qhat_s = qhat_2* qhat_1`` is robot 1's
pose in robot 2's frame (the shape), ``qhat_c = qhat_2 h`` the cluster frame, with ``h`` the
*decoupled* square root of ``qhat_s`` (half the relative rotation, half the relative
translation), so that ``qhat_c`` sits at the robots' midpoint with the half-way yaw
(``docs/derivations.md``, seed 000 items 2-3).

The half-way orientation has two candidates, half a turn apart, at every relative yaw;
the short-way root jumps between them where the relative yaw crosses ``pi``. quatform
takes the branch of the robots' continuous yaws, ``(theta_1 + theta_2)/2``, so the state
is continuous along every motion. The pair ``(qhat_c, qhat_s)`` alone does not tell the
branch: the formation turned half a turn about the cluster's z axis has the same pair on
the other branch. The inverse kinematics therefore picks the root whose robots are
nearest a robot-state hint (the short root without one).
"""

from __future__ import annotations

import numpy as np

from ..algebra._validate import as_unit_dual_quaternion
from ..algebra.operators import dqminus, dqplus, qminus, qplus
from ..errors import UnreachableError
from . import _geometry as g
from .base import Formation, Variable
from .euclidean_pair import EuclideanPair
from .quaternion_pair import TILT_TOL, QuaternionPair

__all__ = ["DualQuaternionPair"]

_QC, _QS = slice(0, 8), slice(8, 16)
_KZ = np.array([0.0, 0.0, 0.0, 1.0])
_C4 = np.diag([1.0, -1.0, -1.0, -1.0])
_C8 = np.diag([1.0, -1.0, -1.0, -1.0, 1.0, -1.0, -1.0, -1.0])


def _dq_variables(prefix):
    return tuple(Variable(f"{prefix}_{p}{c}", "1", "quaternion") for p in "rd" for c in "wxyz")


def _dqmul(a, b):
    ra, da, rb, db = a[..., :4], a[..., 4:], b[..., :4], b[..., 4:]
    return np.concatenate([g.mul(ra, rb), g.mul(ra, db) + g.mul(da, rb)], axis=-1)


def _dqconj(a):
    return a @ _C8


def _pose_dq(q, t):
    tq = np.concatenate([np.zeros(t.shape[:-1] + (1,)), t], axis=-1)
    return np.concatenate([q, 0.5 * g.mul(tq, q)], axis=-1)


def _translation(dq):
    return 2.0 * g.mul(dq[..., 4:], g.conj(dq[..., :4]))[..., 1:]


class DualQuaternionPair(Formation):
    """Seed 000 §3.3: cluster frame ``qhat_c`` and shape ``qhat_s``, two unit dual quaternions."""

    name = "dual-quaternion"
    variables = _dq_variables("qhat_c") + _dq_variables("qhat_s")
    dual_quaternion_slices = (_QC, _QS)

    def check_cluster_state(self, c, name="c"):
        c = super().check_cluster_state(c, name)
        for s, what in zip(self.dual_quaternion_slices, ("qhat_c", "qhat_s")):
            as_unit_dual_quaternion(c[..., s], f"{name}[{what}]")
        return c

    @staticmethod
    def _roots(qs):
        """Both decoupled square roots of the shape ``qs`` (short one first), shape ``(..., 8)``."""
        rs = g.closest_sign(qs[..., :4], np.array([1.0, 0.0, 0.0, 0.0]))
        one = np.zeros_like(rs)
        one[..., 0] = 1.0
        v = one + rs  # w >= 1: never zero
        rh = v / np.linalg.norm(v, axis=-1, keepdims=True)
        rh_long = g.mul(rh, _KZ)  # the other half-way yaw: half a turn more
        half_t = 0.5 * _translation(qs)
        return _pose_dq(rh, half_t), _pose_dq(rh_long, half_t)

    def forward(self, r, hint=None):
        """Eqs. (26)-(27) in closed form: ``qhat_c`` = yaw ``(th1 + th2)/2`` at the midpoint,
        ``qhat_s`` = yaw ``th1 - th2`` at ``R_z(-th2)(p1 - p2)``.

        This is ``qhat_2 (qhat_2* qhat_1)^(1/2)`` with the root on the branch of the robots'
        continuous yaws (``r`` holds unwrapped angles: report yaws mod 2 pi and the mean of
        two angles is only known mod pi). ``hint`` sets the signs.
        """
        r = self.check_robot_state(r)
        self._check_separation(r[..., 0:3] - r[..., 4:7])
        qc = _pose_dq(g.q_yaw(0.5 * (r[..., 3] + r[..., 7])), 0.5 * (r[..., 0:3] + r[..., 4:7]))
        ts = np.einsum("...ij,...j->...i", _rot_z_T(r[..., 7]), r[..., 0:3] - r[..., 4:7])
        qs = _pose_dq(g.q_yaw(r[..., 3] - r[..., 7]), ts)
        if hint is not None:
            hint = self.check_cluster_state(hint, "hint")
            qc = np.where((g.dot(qc[..., :4], hint[..., 0:4]) < 0)[..., None], -qc, qc)
            qs = np.where((g.dot(qs[..., :4], hint[..., 8:12]) < 0)[..., None], -qs, qs)
        return np.concatenate([qc, qs], axis=-1)

    def _branch(self, c, hint_r):
        """Root ``h`` of each state: the one whose robots are nearest ``hint_r`` (short if None)."""
        h, h_long = self._roots(c[..., _QS])
        if hint_r is None:
            return h
        r_short = self._robots(c, h)
        r_long = self._robots(c, h_long)
        hint_r = np.asarray(hint_r, dtype=float)

        def dist(rr):
            dp = np.linalg.norm(rr[..., 0:3] - hint_r[..., 0:3], axis=-1) + np.linalg.norm(
                rr[..., 4:7] - hint_r[..., 4:7], axis=-1)
            return dp + np.abs(g.wrap(rr[..., 3] - hint_r[..., 3])) + np.abs(g.wrap(rr[..., 7] - hint_r[..., 7]))

        return np.where((dist(r_long) < dist(r_short))[..., None], h_long, h)

    @staticmethod
    def _robots(c, h):
        dq2 = _dqmul(c[..., _QC], _dqconj(h))  # qhat_2 = qhat_c h*
        dq1 = _dqmul(dq2, c[..., _QS])  # qhat_1 = qhat_2 qhat_s
        r = np.empty(c.shape[:-1] + (8,))
        for k, dq in ((0, dq1), (4, dq2)):
            r[..., k:k + 3] = _translation(dq)
            r[..., k + 3] = g.yaw_of(dq[..., :4])
        return r

    def inverse(self, c, hint=None):
        """Robots of ``c``: ``qhat_2 = qhat_c h*``, ``qhat_1 = qhat_c h* qhat_s``.

        The form printed under eq. (27) fails at a relative half turn; this one is exact
        (``docs/derivations.md``, seed 000 item 3).
        """
        c = self.check_cluster_state(c)
        for s, what in ((_QC, "qhat_c"), (_QS, "qhat_s")):
            rot = c[..., s][..., :4]
            tilt = np.linalg.norm(g.z_axis(rot) - g.EZ, axis=-1)
            if np.any(tilt > TILT_TOL):
                raise UnreachableError(
                    f"{what} tilts by {float(np.max(tilt)):.3g} rad; with 4-DOF robots its rotation "
                    "must be about z"
                )
        r = self._robots(c, self._branch(c, hint))
        if hint is not None:
            hint = np.asarray(hint, dtype=float)
            for k in (3, 7):
                r[..., k] = g.unwrap_near(r[..., k], hint[..., k])
        return r

    def jacobian(self, r, hint=None):
        """``c_dot = J r_dot`` (16 x 8), from ``qhat_c = (yaw (th1+th2)/2, midpoint)`` and
        ``qhat_s = (yaw th1-th2, R_z(-th2)(p1-p2))``."""
        r = self.check_robot_state(r)
        c = self.forward(r, hint)
        J = np.zeros(r.shape[:-1] + (16, 8))
        for s, rows in ((_QC, slice(0, 8)), (_QS, slice(8, 16))):
            q = c[..., s]
            rot = q[..., :4]
            t = _translation(q)
            d_rot = _rate_column(rot)  # d rot / d angle
            d_angle = np.concatenate([d_rot, 0.5 * g.mul(_pure(t), d_rot)], axis=-1)
            d_t = np.zeros(r.shape[:-1] + (8, 3))
            for k in range(3):
                e = np.zeros(3)
                e[k] = 1.0
                d_t[..., 4:, k] = 0.5 * g.mul(_pure(e), rot)
            if s == _QC:
                J[..., rows, 3] = J[..., rows, 7] = 0.5 * d_angle
                J[..., rows, 0:3] = J[..., rows, 4:7] = 0.5 * d_t
            else:
                R2t = _rot_z_T(r[..., 7])  # R_z(-th2)
                J[..., rows, 3] = d_angle
                # t_s_dot = R_z(-th2)(p1_dot - p2_dot) - th2_dot (z x t_s)
                zx_t = np.stack([-t[..., 1], t[..., 0], np.zeros_like(t[..., 0])], axis=-1)
                J[..., rows, 7] = -d_angle - np.einsum("...ij,...j->...i", d_t, zx_t)
                A = d_t @ R2t
                J[..., rows, 0:3] = A
                J[..., rows, 4:7] = -A
        return J

    def inverse_jacobian_at(self, c, r=None):
        """Derivative of the inverse kinematics at ``c``, shape ``(..., 8, 16)``.

        On the square-root branch of the robots ``r`` (``h = qhat_2* qhat_c``), the short
        root without them.
        """
        c = np.asarray(c, dtype=float)
        qc, qs = c[..., _QC], c[..., _QS]
        if r is None:
            h = self._roots(qs)[0]
        else:
            r = np.asarray(r, dtype=float)
            h = _dqmul(_dqconj(_pose_dq(g.q_yaw(r[..., 7]), r[..., 4:7])), qc)
        dq2 = _dqmul(qc, _dqconj(h))
        dq1 = _dqmul(dq2, qs)
        # derivative of the root h(qs): r_h = n(1 + sig r_s) (r_h k on the long branch),
        # d_h = 1/2 (d_s r_s*) r_h
        rs, ds = qs[..., :4], qs[..., 4:]
        sig = np.where(rs[..., 0] < 0, -1.0, 1.0)[..., None, None]
        v = g.closest_sign(rs, np.array([1.0, 0.0, 0.0, 0.0]))
        v = v.copy()
        v[..., 0] += 1.0
        nv = np.linalg.norm(v, axis=-1)
        n = v / nv[..., None]
        d_n = sig * (np.eye(4) - n[..., :, None] * n[..., None, :]) / nv[..., None, None]
        rh = h[..., :4]
        long = np.abs(g.dot(rh, n)) < 0.5
        d_rh = np.where(long[..., None, None], qminus(_KZ) @ d_n, d_n)
        # h may be either sign of its root: the derivative follows the sign
        n_b = np.where(long[..., None], g.mul(n, _KZ), n)
        d_rh = d_rh * np.where(g.dot(rh, n_b) < 0, -1.0, 1.0)[..., None, None]
        ts2 = g.mul(ds, g.conj(rs))  # t_s / 2 as a quaternion
        dH = np.zeros(c.shape[:-1] + (8, 8))
        dH[..., :4, :4] = d_rh
        dH[..., 4:, :4] = 0.5 * (qminus(rh) @ qplus(ds) @ _C4 + qplus(ts2) @ d_rh)
        dH[..., 4:, 4:] = 0.5 * qminus(rh) @ qminus(g.conj(rs))
        # qhat_2 = qhat_c h*, qhat_1 = qhat_2 qhat_s
        d2_dqc = dqminus(_dqconj(h))
        d2_dqs = dqplus(qc) @ _C8 @ dH
        d1_dqc = dqminus(qs) @ d2_dqc
        d1_dqs = dqminus(qs) @ d2_dqs + dqplus(dq2)
        Ji = np.zeros(c.shape[:-1] + (8, 16))
        for k, dq, dqc_, dqs_ in ((0, dq1, d1_dqc, d1_dqs), (4, dq2, d2_dqc, d2_dqs)):
            P = _pose_partials(dq)  # (..., 4, 8): d(p, theta)/d dq
            Ji[..., k:k + 4, _QC] = P @ dqc_
            Ji[..., k:k + 4, _QS] = P @ dqs_
        return Ji

    def euclidean(self, c, hint=None):
        """Euclidean variables of the robots of ``c``, read through the quaternion cluster frame.

        The dual quaternions carry no frame on the segment, so the branch of ``(beta_c,
        gamma_c)`` near the vertical is taken from ``hint`` (the desired Euclidean state)
        through :meth:`QuaternionPair.euclidean`; without a hint, eqs. (1)-(8). The hint's
        robots also pick the square-root branch of the inverse kinematics.
        """
        if hint is None:
            return EuclideanPair().forward(self.inverse(c))
        r = self.inverse(c, EuclideanPair().inverse(hint))
        qp = QuaternionPair()
        return qp.euclidean(qp.forward(r, qp.from_euclidean(hint)), hint)

    def from_euclidean(self, e, e_dot=None):
        """Closed form, continuous in ``e``: ``qhat_c`` = yaw ``beta + (phi1 + phi2)/2`` at the
        centroid, ``qhat_s`` = yaw ``phi1 - phi2`` at ``R_z(-theta_2)(p1 - p2)``."""
        E = EuclideanPair()
        e = E.check_cluster_state(e, "e")
        r = E.inverse(e)
        beta = e[..., 3]
        qc = _pose_dq(g.q_yaw(beta + 0.5 * (e[..., 6] + e[..., 7])), e[..., 0:3])
        ts = np.einsum("...ij,...j->...i", _rot_z_T(r[..., 7]), r[..., 0:3] - r[..., 4:7])
        qs = _pose_dq(g.q_yaw(e[..., 6] - e[..., 7]), ts)
        c = np.concatenate([qc, qs], axis=-1)
        if e_dot is None:
            return c
        r_dot = np.einsum("...ij,...j->...i", E.inverse_jacobian_at(e), E.check_cluster_state(e_dot, "e_dot"))
        return c, np.einsum("...ij,...j->...i", self.jacobian(r, c), r_dot)


def _pure(v):
    return np.concatenate([np.zeros(np.shape(v)[:-1] + (1,)), v], axis=-1)


def _rate_column(q):
    return 0.5 * g.mul(_KZ, q)


def _rot_z_T(theta):
    c, s = np.cos(theta), np.sin(theta)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, s, z], -1), np.stack([-s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _pose_partials(dq):
    """``d(p, theta)/d dq`` at a unit pose ``dq``: ``p = 2 vec(d r*)``, ``theta = yaw(r)``, (..., 4, 8)."""
    r, d = dq[..., :4], dq[..., 4:]
    P = np.zeros(dq.shape[:-1] + (4, 8))
    P[..., 0:3, 0:4] = 2.0 * (qplus(d) @ _C4)[..., 1:, :]
    P[..., 0:3, 4:8] = 2.0 * qminus(g.conj(r))[..., 1:, :]
    P[..., 3, 0:4] = g.d_yaw_of(r)
    return P
