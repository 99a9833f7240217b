"""Dual-quaternion cluster space of two 4-DOF robots, seed 000 eqs. (26)-(27).

Formations layer. ``c = (qhat_c[8], qhat_s[8])``: ``qhat_s = qhat_2* qhat_1`` is robot 1's
pose in robot 2's frame (the shape), ``qhat_c = qhat_2 h`` the cluster frame, with ``h`` the
*decoupled* square root of ``qhat_s`` (half the relative rotation, half the relative
translation), so that ``qhat_c`` sits at the robots' midpoint with the half-way yaw
(``docs/derivations.md``, seed 000 items 2-3).

The half-way yaw of two yaws is only defined mod pi: two cluster frames, half a turn
apart, sit half-way between the robots. quatform takes the branch of the robots'
continuous yaws, ``(theta_1 + theta_2)/2``, so the state is continuous along every motion,
and records the branch in the **sign of** ``qhat_s``: ``h`` is the root of ``qhat_s``
itself (``h^2 = +qhat_s``), unique up to sign. So ``(+-qhat_c, qhat_s)`` and
``(+-qhat_c k, -qhat_s)`` (``k`` the half turn about the cluster's z axis) are one
formation, and ``(qhat_c, -qhat_s)`` is that formation turned half a turn about the
cluster's z axis (the robots swapped): ``inverse(forward(r)) = r`` without a hint
(``docs/derivations.md``, "The two-robot formations and controllers (seed 000)").
"""

from __future__ import annotations

import numpy as np

from ..algebra.validate import as_array, as_unit_dual_quaternion
from ..errors import DegenerateInputError, UnreachableError
from . import geometry as g
from . import pair_kernels as kern
from . import special_sets as sp
from .base import MIN_SEPARATION_M, Formation, Variable
from .euclidean_team import EUCLIDEAN_VARIABLES, EuclideanPair
from .quaternion_pair import TILT_TOL, QuaternionPair

__all__ = ["DualQuaternionPair"]

_QC, _QS = slice(0, 8), slice(8, 16)
_KZ = np.array([0.0, 0.0, 0.0, 1.0])


def _dq_variables(prefix):
    return tuple(Variable(f"{prefix}_{p}{c}", "1", "quaternion") for p in "rd" for c in "wxyz")


# Array forms of the component kernels (one formula each, in pair_kernels).
def _dqmul(a, b):
    return kern.pack(kern.dqmul(kern.unpack(a), kern.unpack(b)))


def _dqconj(a):
    return kern.pack(kern.dqconj(kern.unpack(a)))


def _pose_dq(q, t):
    return kern.pack(kern.pose(kern.unpack(np.asarray(q)), kern.unpack(np.asarray(t))))


def _translation(dq):
    return kern.pack(kern.translation(kern.unpack(np.asarray(dq))))


class DualQuaternionPair(Formation):
    """Seed 000 §3.3: cluster frame ``qhat_c`` and shape ``qhat_s``, two unit dual quaternions."""

    name = "dual-quaternion"
    key = "dual-quaternion"
    variables = _dq_variables("qhat_c") + _dq_variables("qhat_s")
    chart_variables = EUCLIDEAN_VARIABLES
    dual_quaternion_slices = (_QC, _QS)
    #: ``qhat_c``'s sign means nothing; ``qhat_s``'s is the branch of the half-way yaw (module docstring).
    sign_free = (_QC,)

    def special_sets(self):
        return sp.pair_sets("beta_c is undefined here; the dual quaternions are regular")

    def check_cluster_state(self, c, name="c"):
        c = super().check_cluster_state(c, name)
        for s, what in zip(self.dual_quaternion_slices, ("qhat_c", "qhat_s")):
            as_unit_dual_quaternion(c[..., s], f"{name}[{what}]")
        return c

    @staticmethod
    def _root(qs):
        """The decoupled square root ``h`` of the signed shape ``qs``, shape ``(..., 8)``.

        ``h = (q_yaw(theta_s / 2), t_s / 2)`` with ``theta_s / 2 = atan2(qs_z, qs_w)``, so that
        ``h_p^2 = +qs_p`` (not ``-qs_p``): the root of ``qs`` and of ``-qs`` are half a turn
        apart, and which one is meant is the sign of ``qs`` (seed 000 eq. (26)). The yaw
        part of the rotation is used (the state is checked to be a yaw first).
        """
        rh = g.q_yaw(np.arctan2(qs[..., 3], qs[..., 0]))
        return _pose_dq(rh, 0.5 * _translation(qs))

    def forward(self, r, *, near_c=None):
        """Eqs. (26)-(27) in closed form: ``qhat_c`` = yaw ``(th1 + th2)/2`` at the midpoint,
        ``qhat_s`` = yaw ``th1 - th2`` at ``R_z(-th2)(p1 - p2)``.

        Parameters
        ----------
        r : array_like, shape (..., 8)
            Robot states, m and rad; the yaws are read as real numbers (their branch sets
            the sign of ``qhat_s``; every branch is the same formation, see the module).
        near_c : array_like, shape (..., 16), optional
            A cluster state to stay near: the yaws of ``r`` are first moved by whole turns
            onto its branch (:func:`~.pair_kernels.dq_align_yaws`, as the controller
            does), and ``qhat_c`` takes its sign. The result is the same formation as
            ``r`` whatever ``near_c``.

        Returns
        -------
        ndarray, shape (..., 16)
        """
        r = self.check_robot_state(r)
        self.check_apart(r)
        return self.forward_arrays(r, None if near_c is None else self.check_cluster_state(near_c, "near_c"))

    def forward_arrays(self, r, near_c=None):
        """:meth:`forward` of checked arrays of any namespace (NumPy, JAX), no check."""
        if near_c is None:
            return kern.pack(kern.dq_forward(kern.unpack(r)))
        h = kern.unpack(near_c)
        rr = kern.dq_align_yaws(kern.unpack(r), *kern.dq_yaws(h))
        return kern.pack(kern.dq_forward(rr, h[0:4]))

    #: The singularity measure on any array namespace (Formation.singularity_measure_arrays);
    #: the chart (through :meth:`inverse` and the quaternion pair's) on NumPy only.
    singularity_on_arrays = True
    rates_read_robots = True

    component_kernels = True

    def forward_components(self, rc, near_c, stage=None):
        """Eqs. (26)-(27) on components for a controller: the measured yaws moved by whole
        turns onto ``near_c``'s branch (each within pi of the desired robot's, the shape's
        relative-yaw error within 3 pi / 2; the sign of ``qhat_s`` is the branch), ``qhat_c``
        with ``near_c``'s sign: ``(c, rc)`` with ``rc`` the wound robots."""
        rc = kern.dq_align_yaws(rc, *kern.dq_yaws(near_c))
        kern.check_apart(rc, MIN_SEPARATION_M)
        return kern.dq_forward(rc, near_c[0:4], stage=stage), rc

    def robot_rate_components(self, c, c_dot, rc):
        """:meth:`robot_rate` on components (:func:`~.pair_kernels.dq_inverse_jvp`)."""
        return kern.dq_inverse_jvp(c, c_dot, rc)

    def _robots(self, c, h):
        dq2 = _dqmul(c[..., _QC], _dqconj(h))  # qhat_2 = qhat_c h*
        dq1 = _dqmul(dq2, c[..., _QS])  # qhat_1 = qhat_2 qhat_s
        return self.layout.compose(np.stack([_translation(dq1), _translation(dq2)], axis=-2),
                                   np.stack([g.yaw_of(dq1[..., :4]), g.yaw_of(dq2[..., :4])], axis=-1))

    def inverse(self, c, *, near_r=None):
        """Robots of ``c``: ``qhat_2 = qhat_c h*``, ``qhat_1 = qhat_c h* qhat_s``.

        The form printed under eq. (27) fails at a relative half turn; this one is exact
        (``docs/derivations.md``, seed 000 item 3). ``h`` is the root of the signed
        ``qhat_s`` (:meth:`_root`), so the result needs no branch choice.

        Parameters
        ----------
        c : array_like, shape (..., 16)
            Unit dual quaternions ``qhat_c``, ``qhat_s`` whose rotations are yaws.
        near_r : array_like, shape (..., 8), optional
            Robot state whose yaws the result's are unwrapped near (within pi); it does not
            change the formation.

        Returns
        -------
        ndarray, shape (..., 8)
            ``(x1, y1, z1, theta1, x2, y2, z2, theta2)``, m and rad (yaws in ``(-pi, pi]``
            without ``near_r``).

        Raises
        ------
        UnreachableError
            If a rotation is not about z (a 4-DOF robot cannot roll or pitch).
        DegenerateInputError
            If the shape's translation is shorter than the robots' minimum separation.
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
        sep = np.linalg.norm(_translation(c[..., _QS]), axis=-1)
        if np.any(sep < MIN_SEPARATION_M):
            raise DegenerateInputError(
                f"qhat_s translates by {float(np.min(sep)):.3g} m: the two robots would coincide; "
                f"the shape must separate them by at least {MIN_SEPARATION_M:g} m"
            )
        if near_r is not None:
            near_r = self.check_robot_state(near_r, "near_r")
        r = self._robots(c, self._root(c[..., _QS]))
        if near_r is not None:
            for k in self.layout.yaw_indices:
                r[..., k] = g.unwrap_near(r[..., k], near_r[..., k])
        return r

    def cluster_rate(self, r, r_dot, *, near_c=None):
        """``c_dot = J r_dot``: the derivative of the closed form of eqs. (26)-(27),
        ``qhat_c = (yaw (th1+th2)/2, midpoint)``, ``qhat_s = (yaw th1-th2, R_z(-th2)(p1-p2))``.

        A pose ``(q_yaw(theta), t)`` moves at ``theta' d_angle + (0, 1/2 (0, t') q)`` with
        ``d_angle = (1/2 k q, 1/4 (0, t) k q)``; ``t_s' = R_z(-th2)(p1' - p2') - th2' (z x t_s)``.
        """
        r = self.check_robot_state(r)
        c = self.forward(r, near_c=near_c)
        r_dot = as_array(r_dot, "r_dot", 8)
        L = self.layout
        v, w = L.positions(r_dot), L.yaws(r_dot)
        parts = []
        for s in (_QC, _QS):
            q = c[..., s]
            rot, t = q[..., :4], _translation(q)
            d_rot = _rate_column(rot)  # d rot / d angle
            d_angle = np.concatenate([d_rot, 0.5 * g.mul(_pure(t), d_rot)], axis=-1)
            # d (dual part) / d t = 1/2 (0, e_k) rot, k = x, y, z: (..., 4, 3)
            d_t = np.stack([0.5 * g.mul(_pure(e), rot) for e in np.eye(3)], axis=-1)
            if s == _QC:
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
        """Derivative of the inverse kinematics at ``c`` along ``c_dot``.

        ``r``, the robots of ``c`` (computed by :meth:`inverse` if not given), supplies
        ``theta_2``. Along the description's 8-dimensional manifold this is the derivative of
        ``qhat_2 = qhat_c h*``, ``qhat_1 = qhat_2 qhat_s``; see
        :func:`~quatform.formations.pair_kernels.dq_inverse_jvp`.
        """
        c = np.asarray(c, dtype=float)
        return self.robot_rate_arrays(c, as_array(c_dot, "c_dot", 16), r=np.asarray(self.inverse(c) if r is None else r,
                                                                                  dtype=float))

    def robot_rate_arrays(self, c, cd, r):
        """:meth:`robot_rate` of arrays of any namespace, ``r`` the robots of ``c``; no check."""
        return kern.pack(kern.dq_inverse_jvp(kern.unpack(c), kern.unpack(cd), kern.unpack(r)))

    def to_chart(self, c, *, near_e=None, r=None):
        """Euclidean variables of the robots of ``c``, read through the quaternion cluster frame.

        The dual quaternions carry no frame on the segment, so the branch of ``(beta_c,
        gamma_c)`` near the vertical is taken from ``near_e`` (the desired Euclidean state)
        through :meth:`QuaternionPair.to_chart`; without it, eqs. (1)-(8). ``r`` (the
        measured robots) or else the robots of ``near_e`` only unwrap the yaws: ``c`` itself
        fixes the formation.
        """
        near = r if r is not None else (None if near_e is None else EuclideanPair().inverse(near_e))
        r = self.inverse(c, near_r=near)
        if near_e is None:
            return EuclideanPair().forward(r)
        qp = QuaternionPair()
        return qp.to_chart(qp.forward(r, near_c=qp.from_chart(near_e)), near_e=near_e)

    def from_chart(self, e, e_dot=None):
        """Closed form, continuous in ``e``: ``qhat_c`` = yaw ``beta + (phi1 + phi2)/2`` at the
        centroid, ``qhat_s`` = yaw ``phi1 - phi2`` at ``R_z(-theta_2)(p1 - p2)``."""
        E = EuclideanPair()
        e = E.check_cluster_state(e, "e")
        r = E.inverse(e)
        beta = e[..., 3]
        qc = _pose_dq(g.q_yaw(beta + 0.5 * (e[..., 6] + e[..., 7])), e[..., 0:3])
        p = self.layout.positions(r)
        ts = np.einsum("...ij,...j->...i", _rot_z_T(self.layout.yaws(r)[..., 1]), p[..., 0, :] - p[..., 1, :])
        qs = _pose_dq(g.q_yaw(e[..., 6] - e[..., 7]), ts)
        c = np.concatenate([qc, qs], axis=-1)
        if e_dot is None:
            return c
        # the dense matrices (not the rate maps) keep the rounding the reference runs were recorded with
        r_dot = np.einsum("...ij,...j->...i", E.inverse_jacobian_at(e), as_array(e_dot, "e_dot", 8))
        return c, np.einsum("...ij,...j->...i", self.jacobian(r, near_c=c), r_dot)


def _pure(v):
    return np.concatenate([np.zeros(np.shape(v)[:-1] + (1,)), v], axis=-1)


def _rate_column(q):
    return 0.5 * g.mul(_KZ, q)


def _rot_z_T(theta):
    c, s = np.cos(theta), np.sin(theta)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, s, z], -1), np.stack([-s, c, z], -1), np.stack([z, z, o], -1)], -2)
