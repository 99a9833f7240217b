"""Quaternion cluster space of two 4-DOF robots, seed 000 eqs. (9)-(19).

Formations layer. ``c = (x_c, y_c, z_c, q_c[4], d_c, q_c1[4], q_c2[4])``: the centroid, a
unit quaternion whose x axis points from robot 2 to robot 1, half the separation, and each
robot's orientation in the cluster frame. 16 numbers for 8 degrees of freedom.

The twist of ``q_c`` about the segment is not a function of the robots' positions. The
seed fixes it with the minimal rotation from ``i`` (eqs. (14)-(15)), which is undefined
where ``x1 - x2`` points along ``-i`` (``eta = pi``, ``n_12 = 0/0``); no choice made from
positions alone can avoid such a point (there is no continuous section of S^3 -> S^2).
quatform therefore takes the twist from ``near_c`` (the desired cluster state): the
measured ``q_c`` is the point of its fibre nearest it. The only remaining choice is
a measured segment exactly opposite the hinted one, a 180 deg formation error, where the
half turn about the hint's z axis is taken.
"""

from __future__ import annotations

import numpy as np

from ..algebra.angles import map_entries
from ..algebra.kernels import array_namespace as namespace
from ..algebra.validate import as_array, as_unit_quaternion
from ..errors import DegenerateInputError, UnreachableError
from . import geometry as g
from . import pair_kernels as kern
from . import special_sets as sp
from .base import MIN_SEPARATION_M, Formation, Variable, quaternion_variables
from .euclidean_team import EUCLIDEAN_VARIABLES, EuclideanPair

__all__ = ["QuaternionPair"]

_XC, _QC, _D, _Q1, _Q2 = slice(0, 3), slice(3, 7), 7, slice(8, 12), slice(12, 16)
_KZ = np.array([0.0, 0.0, 0.0, 1.0])
#: Below this horizontal fraction of the segment, monitoring reads the yaw from q_c's y axis.
NEAR_VERTICAL = 1e-2
#: Largest tilt (rad) of a robot's orientation that a 4-DOF robot is taken to reach.
TILT_TOL = 1e-6


def _yaw_rate_column(q):
    """``d q / d theta`` for a yaw rotation about world z: ``1/2 (0, 0, 0, 1) q``."""
    return 0.5 * g.mul(_KZ, q)


class QuaternionPair(Formation):
    """Seed 000 §3.2: centroid, cluster quaternion, half-separation, robot quaternions."""

    name = "quaternion"
    key = "quaternion"
    variables = (
        Variable("x_c", "m", "position"),
        Variable("y_c", "m", "position"),
        Variable("z_c", "m", "position"),
        *quaternion_variables("q_c"),
        Variable("d_c", "m", "length"),
        *quaternion_variables("q_c1"),
        *quaternion_variables("q_c2"),
    )
    chart_variables = EUCLIDEAN_VARIABLES
    #: Index groups of the unit quaternions in ``c`` (for errors and sign handling).
    quaternion_slices = (_QC, _Q1, _Q2)
    sign_free = (_QC, _Q1, _Q2)

    def special_sets(self):
        return sp.pair_sets("beta_c is undefined here; q_c is regular (its twist taken from near_c)")

    def check_cluster_state(self, c, name="c"):
        c = super().check_cluster_state(c, name)
        for s, what in zip(self.quaternion_slices, ("q_c", "q_c1", "q_c2")):
            as_unit_quaternion(c[..., s], f"{name}[{what}]")
        return c

    # -- kinematics -------------------------------------------------------------------
    def forward(self, r, *, near_c=None):
        r = self.check_robot_state(r)
        self.check_apart(r)
        return self.forward_arrays(r, None if near_c is None else self.check_cluster_state(near_c, "near_c"))

    def forward_arrays(self, r, near_c=None):
        """:meth:`forward` of checked arrays of any namespace (NumPy, JAX), no check."""
        if near_c is None:
            # eqs. (10), (14), (15): the minimal rotation from i (near q_c = 1)
            return kern.pack(kern.quat_forward(kern.unpack(r), (1.0, 0.0, 0.0, 0.0)))
        h = kern.unpack(near_c)
        return kern.pack(kern.quat_forward(kern.unpack(r), h[3:7], h[8:12], h[12:16]))

    #: The singularity measure and the chart on any array namespace (Formation.singularity_measure_arrays).
    singularity_on_arrays = True
    chart_on_arrays = True

    component_kernels = True

    def forward_components(self, rc, near_c, stage=None):
        """Eqs. (10)-(15) on components, the twists of ``q_c``, ``q_c1``, ``q_c2`` from
        ``near_c`` (the controller's reference): ``(c, rc)`` (``stage``:
        :func:`~.pair_kernels.quat_forward`'s)."""
        kern.check_apart(rc, MIN_SEPARATION_M)
        return kern.quat_forward(rc, near_c[3:7], near_c[8:12], near_c[12:16], stage=stage), rc

    def robot_rate_components(self, c, c_dot, rc):
        """:meth:`robot_rate` on components (:func:`~.pair_kernels.quat_inverse_jvp`)."""
        return kern.quat_inverse_jvp(c, c_dot)

    def inverse(self, c, *, near_r=None):
        c = self.check_cluster_state(c)
        qc = c[..., _QC] / np.linalg.norm(c[..., _QC], axis=-1, keepdims=True)
        d = c[..., _D]
        if np.any(d < 0.5 * MIN_SEPARATION_M):
            raise DegenerateInputError(
                f"d_c must be at least {0.5 * MIN_SEPARATION_M:g} m (half the robots' separation), "
                f"got {float(np.min(d))!r}; a smaller d_c puts the robots on each other"
            )
        half = d[..., None] * g.x_axis(qc)  # seed 000 eqs. (16), (18)
        yaws = []
        for k, s in ((1, _Q1), (2, _Q2)):
            qi = g.mul(qc, c[..., s])  # eqs. (17), (19)
            tilt = np.linalg.norm(g.z_axis(qi / np.linalg.norm(qi, axis=-1, keepdims=True)) - g.EZ, axis=-1)
            if np.any(tilt > TILT_TOL):
                raise UnreachableError(
                    f"q_c q_c{k} tilts the robot by {float(np.max(tilt)):.3g} rad; "
                    "a 4-DOF robot only yaws - give robot quaternions that are rotations about z"
                )
            yaws.append(g.yaw_of(qi))
        th = np.stack(yaws, axis=-1)
        if near_r is not None:
            th = g.unwrap_near(th, self.layout.yaws(self.check_robot_state(near_r, "near_r")))
        return self.layout.compose(np.stack([c[..., _XC] + half, c[..., _XC] - half], axis=-2), th)

    # -- rate maps --------------------------------------------------------------------
    def cluster_rate(self, r, r_dot, *, near_c=None):
        """``c_dot = J r_dot`` for the forward map near ``near_c`` (no twist rate of ``q_c``).

        Derivative of eqs. (9)-(15): ``x_c' = (p1' + p2')/2``; ``q_c' = 1/2 (0, w) q_c`` with
        ``w = u x delta' / D`` (the minimal rotation of the segment ``u = delta / D``);
        ``d_c' = u . delta' / 2``; ``q_ci' = (q_c')* q_i + q_c* q_i'`` with ``q_i' = 1/2
        theta_i' (0, 0, 0, 1) q_i`` (eqs. (12)-(13)).
        """
        c = self.forward(r, near_c=near_c)
        r_dot = as_array(r_dot, "r_dot", 8)
        L = self.layout
        v, th_dot = L.positions(r_dot), L.yaws(r_dot)
        qc = c[..., _QC]
        u = g.x_axis(qc)
        D = 2.0 * c[..., _D]
        dd = v[..., 0, :] - v[..., 1, :]
        omega = np.cross(u, dd) / D[..., None]
        qc_dot = 0.5 * g.mul(np.concatenate([np.zeros(omega.shape[:-1] + (1,)), omega], axis=-1), qc)
        parts = [0.5 * (v[..., 0, :] + v[..., 1, :]), qc_dot, 0.5 * np.sum(u * dd, axis=-1)[..., None]]
        conj_qc_dot = g.conj(qc_dot)
        for k, s in ((0, _Q1), (1, _Q2)):
            qi = g.mul(qc, c[..., s])
            parts.append(g.mul(conj_qc_dot, qi) + th_dot[..., k, None] * g.mul(g.conj(qc), _yaw_rate_column(qi)))
        return g.concat(parts)

    def robot_rate(self, c, c_dot, *, r=None):
        """Derivative of eqs. (16)-(19) at ``c`` along ``c_dot``: the 8 x 16 matrix of seed 000
        Fig. 6 applied to ``c_dot`` (:func:`~.pair_kernels.quat_inverse_jvp`)."""
        return self.robot_rate_arrays(np.asarray(c, dtype=float), as_array(c_dot, "c_dot", 16))

    def robot_rate_arrays(self, c, cd):
        """:meth:`robot_rate` of arrays of any namespace, no check."""
        return kern.pack(kern.quat_inverse_jvp(kern.unpack(c), kern.unpack(cd)))

    # -- monitoring and references ----------------------------------------------------
    def to_chart(self, c, *, near_e=None, r=None):
        """Euclidean variables of ``c`` on the whole circle, regular at ``gamma_c = +-pi/2``.

        For a frame without twist (``q_c = q_z(beta + pi/2) q_y(-gamma)``) the y axis is
        ``(-cos beta, -sin beta, 0)``. Within ``NEAR_VERTICAL`` rad of the vertical, where
        eq. (4) is 0/0 or ill-conditioned, ``beta`` is read from the y axis and ``gamma`` from
        the segment in the frame turned by ``beta`` (exact for a twist-free frame, off by
        less than the twist times ``NEAR_VERTICAL`` otherwise); elsewhere ``beta`` and
        ``gamma`` are eqs. (4)-(5) of the segment, exactly, on the branch (``beta``,
        ``gamma``) or (``beta + pi``, ``pi - gamma``) that the y axis points to. ``u`` and
        ``y`` are orthogonal unit vectors, so ``y`` is far from vertical where ``u`` is near it.
        """
        c = self.check_cluster_state(c)
        return self.to_chart_arrays(c, None if near_e is None else np.asarray(near_e, dtype=float))

    def to_chart_arrays(self, c, near_e=None, r=None):
        """:meth:`to_chart` of checked arrays of any namespace (NumPy, JAX), the branches selected."""
        xp = namespace(c)
        qc = c[..., _QC]
        y = g.rotate(qc, np.array([0.0, 1.0, 0.0]))
        u = g.x_axis(qc)
        rho_u, rho_y = xp.hypot(u[..., 0], u[..., 1]), xp.hypot(y[..., 0], y[..., 1])
        # near the vertical: beta from the y axis
        beta_y = xp.arctan2(-y[..., 1], -y[..., 0])
        psi = beta_y + 0.5 * np.pi
        gamma_y = xp.arctan2(u[..., 2], xp.cos(psi) * u[..., 0] + xp.sin(psi) * u[..., 1])
        # elsewhere: eqs. (4)-(5), branch from the y axis
        beta_u = xp.arctan2(-u[..., 0], u[..., 1])
        gamma_u = xp.arctan2(u[..., 2], rho_u)
        other = -(xp.cos(beta_u) * y[..., 0] + xp.sin(beta_u) * y[..., 1]) < 0.0
        beta_u = xp.where(other, beta_u + np.pi, beta_u)
        gamma_u = xp.where(other, np.pi - gamma_u, gamma_u)
        use_y = rho_u < NEAR_VERTICAL * rho_y
        beta = g.wrap(xp.where(use_y, beta_y, beta_u))
        gamma = g.wrap(xp.where(use_y, gamma_y, gamma_u))
        phi = [g.wrap(g.yaw_of(g.mul(qc, c[..., s])) - beta) for s in (_Q1, _Q2)]
        e = xp.stack([c[..., 0], c[..., 1], c[..., 2], beta, gamma, c[..., 7], *phi], axis=-1)
        if near_e is None:
            return e
        return map_entries(e, (3, 4, 6, 7), lambda a, b: g.unwrap_near(e[..., a:b], near_e[..., a:b]))

    def from_chart(self, e, e_dot=None):
        """``q_c = q_z(beta + pi/2) q_y(-gamma)``, ``q_ci = q_c* q_z(phi_i + beta)``: continuous in ``e``."""
        e = EuclideanPair().check_cluster_state(e, "e")
        beta, gamma = e[..., 3], e[..., 4]
        qz, qy = g.q_yaw(beta + 0.5 * np.pi), g.q_pitch_y(-gamma)
        qc = g.mul(qz, qy)
        q1, q2 = g.q_yaw(e[..., 6] + beta), g.q_yaw(e[..., 7] + beta)
        c = np.empty(e.shape[:-1] + (16,))
        c[..., _XC] = e[..., 0:3]
        c[..., _QC] = qc
        c[..., _D] = e[..., 5]
        c[..., _Q1] = g.mul(g.conj(qc), q1)
        c[..., _Q2] = g.mul(g.conj(qc), q2)
        if e_dot is None:
            return c
        ed = as_array(e_dot, "e_dot", 8)
        qc_dot = ed[..., 3, None] * g.mul(_yaw_rate_column(qz), qy) + g.mul(
            qz, -ed[..., 4, None] * 0.5 * g.mul(qy, np.array([0.0, 0.0, 1.0, 0.0]))
        )
        cd = np.empty_like(c)
        cd[..., _XC] = ed[..., 0:3]
        cd[..., _QC] = qc_dot
        cd[..., _D] = ed[..., 5]
        for sl, qi, k in ((_Q1, q1, 6), (_Q2, q2, 7)):
            qi_dot = (ed[..., k] + ed[..., 3])[..., None] * _yaw_rate_column(qi)
            cd[..., sl] = g.mul(g.conj(qc_dot), qi) + g.mul(g.conj(qc), qi_dot)
        return c, cd
