"""Euclidean cluster space of two 4-DOF robots, seed 000 eqs. (1)-(8), and the robot space.

Formations layer. ``EuclideanPair`` is the minimal (8-variable) baseline of Mas & Kitts:
``c = (x_c, y_c, z_c, beta_c, gamma_c, d_c, phi_1, phi_2)``; it is singular where the
segment between the robots is vertical (``|gamma_c| = pi/2``: ``beta_c`` undefined) and
where the robots coincide. ``RobotSpace`` is the identity description used by the
robot-space controller of seed 000 §3.1.
"""

from __future__ import annotations

import numpy as np

from ..algebra.angles import map_entries
from ..algebra.kernels import array_namespace as namespace
from ..algebra.kernels import concrete
from ..algebra.validate import as_array
from ..errors import DegenerateInputError
from . import geometry as g
from . import special_sets as sp
from .base import MIN_SEPARATION_M, ROBOT_PAIR_VARIABLES, Formation, Variable

__all__ = ["EuclideanPair", "RobotSpace", "EUCLIDEAN_VARIABLES"]

#: Layout of the Euclidean cluster state (seed 000 §2).
EUCLIDEAN_VARIABLES = (
    Variable("x_c", "m", "position"),
    Variable("y_c", "m", "position"),
    Variable("z_c", "m", "position"),
    Variable("beta_c", "rad", "angle"),
    Variable("gamma_c", "rad", "angle"),
    Variable("d_c", "m", "length"),
    Variable("phi_1", "rad", "angle"),
    Variable("phi_2", "rad", "angle"),
)

#: Below this ratio of horizontal to full separation ``beta_c`` is taken as undefined.
VERTICAL_TOL = 1e-12


def segment_direction(beta, gamma):
    """Unit vector from robot 2 to robot 1 for cluster yaw ``beta`` and pitch ``gamma``.

    Inverse of seed 000 eqs. (4)-(5): ``(-sin b cos g, cos b cos g, sin g)``. Shape ``(..., 3)``.
    """
    xp = namespace(beta)
    cb, sb, cg, sg = xp.cos(beta), xp.sin(beta), xp.cos(gamma), xp.sin(gamma)
    return xp.stack([-sb * cg, cb * cg, sg], axis=-1)


def _direction_partials(beta, gamma):
    xp = namespace(beta)
    cb, sb, cg, sg = xp.cos(beta), xp.sin(beta), xp.cos(gamma), xp.sin(gamma)
    u_b = xp.stack([-cb * cg, -sb * cg, xp.zeros_like(cb)], axis=-1)
    u_g = xp.stack([sb * sg, -cb * sg, cg], axis=-1)
    return u_b, u_g


class EuclideanPair(Formation):
    """Seed 000 eqs. (1)-(8): position, yaw, pitch, half-separation and relative yaws.

    Eq. (6) is printed ``sqrt(dx^2 + dy^2 + dz^2/2)``; ``d_c`` is *half the distance*
    (text and Fig. 1), i.e. ``sqrt(dx^2 + dy^2 + dz^2) / 2`` (``docs/derivations.md``).
    ``gamma_c`` lies in ``[-pi/2, pi/2]`` (the range of eq. (5)); a pitch beyond it is
    read as ``beta_c + pi`` and ``pi - gamma_c``, the ambiguity of seed 000 §4.1.
    """

    name = "euclidean"
    key = "euclidean"
    variables = EUCLIDEAN_VARIABLES
    chart_variables = EUCLIDEAN_VARIABLES

    def check_cluster_state(self, c, name="c"):
        c = super().check_cluster_state(c, name)
        if np.any(c[..., 5] < 0.5 * MIN_SEPARATION_M):
            raise DegenerateInputError(
                f"{name}: d_c must be at least {0.5 * MIN_SEPARATION_M:g} m (half the robots' "
                f"separation), got {float(np.min(c[..., 5]))!r}; a smaller d_c puts the robots on "
                "each other, a negative one would swap them"
            )
        return c

    def forward(self, r, *, near_c=None):
        r = self.check_robot_state(r)
        if near_c is not None:
            near_c = self.check_cluster_state(near_c, "near_c")
        c = self.forward_arrays(r, near_c)
        self.check_apart(r, separations=2.0 * c[..., 5])  # D = 2 d_c exactly
        return c

    def forward_arrays(self, r, near_c=None):
        """Eqs. (1)-(8) of checked robot states ``r`` (``(..., 8)``, NumPy or another array
        namespace, e.g. JAX under ``jax.jit``), with :meth:`forward`'s branch rule for ``near_c``;
        no check (robots apart, finite values: the caller's)."""
        xp = namespace(r)
        p = self.layout.positions(r)
        th = self.layout.yaws(r)
        p1, p2 = p[..., 0, :], p[..., 1, :]
        delta = p1 - p2
        D = g.norm(delta)
        rho = xp.hypot(delta[..., 0], delta[..., 1])
        mid = 0.5 * (p1 + p2)  # seed 000 eqs. (1)-(3)
        beta = xp.arctan2(-delta[..., 0], delta[..., 1])  # eq. (4)
        gamma = xp.arctan2(delta[..., 2], rho)  # eq. (5)
        if near_c is not None:
            beta = xp.where(rho <= VERTICAL_TOL * D, near_c[..., 3], g.unwrap_near(beta, near_c[..., 3]))
            phi1 = g.unwrap_near(th[..., 0] - beta, near_c[..., 6])  # eqs. (7)-(8)
            phi2 = g.unwrap_near(th[..., 1] - beta, near_c[..., 7])
        else:
            phi1, phi2 = g.wrap(th[..., 0] - beta), g.wrap(th[..., 1] - beta)
        # eq. (6), corrected: d_c = D / 2
        return xp.stack([mid[..., 0], mid[..., 1], mid[..., 2], beta, gamma, 0.5 * D, phi1, phi2], axis=-1)

    def inverse(self, c, *, near_r=None):
        """Robots of the Euclidean cluster state ``c``: the inverse of eqs. (1)-(8).

        ``x1,2 = x_c +- d_c (-sin beta cos gamma, cos beta cos gamma, sin gamma)`` (seed 000
        eqs. (1)-(6) solved for the positions) and ``theta_i = phi_i + beta_c`` (eqs.
        (7)-(8)). Single-valued: every ``c`` names one formation. A pitch beyond
        ``[-pi/2, pi/2]`` is accepted: its positions are those of ``(beta + pi, pi - gamma)``
        (the fold of seed 000 §4.1), its yaws ``phi_i + beta`` as given. At ``gamma_c =
        +-pi/2`` the positions do not depend on ``beta_c`` (the vertical singularity), the
        yaws still do.

        Parameters
        ----------
        c : array_like, shape (..., 8)
            ``(x_c, y_c, z_c, beta_c, gamma_c, d_c, phi_1, phi_2)``: m, rad, ``d_c`` in m
            (at least ``MIN_SEPARATION_M / 2``).
        near_r : array_like, shape (..., 8), optional
            Robot state whose yaws the result's are unwrapped near (within pi); without it
            the yaws are ``phi_i + beta_c`` as given.

        Returns
        -------
        ndarray, shape (..., 8)
            ``(x1, y1, z1, theta1, x2, y2, z2, theta2)``, m and rad.

        Raises
        ------
        DegenerateInputError
            If ``d_c`` is below half the minimum separation (the robots would coincide).
        """
        c = self.check_cluster_state(c)
        u = segment_direction(c[..., 3], c[..., 4])
        half = c[..., 5:6] * u
        th = np.stack([c[..., 6] + c[..., 3], c[..., 7] + c[..., 3]], axis=-1)
        if near_r is not None:
            th = g.unwrap_near(th, self.layout.yaws(self.check_robot_state(near_r, "near_r")))
        return self.layout.compose(np.stack([c[..., 0:3] + half, c[..., 0:3] - half], axis=-2), th)

    def cluster_rate(self, r, r_dot, *, near_c=None):
        """Derivative of eqs. (1)-(8) along ``r_dot``; undefined (raises) at a vertical segment.

        ``x_c' = (p1' + p2')/2``; ``beta_c' = grad beta . delta'``, ``gamma_c' = grad gamma .
        delta'``, ``d_c' = delta . delta' / (2 D)`` with ``delta = p1 - p2`` (eqs. (4)-(6));
        ``phi_i' = theta_i' - beta_c'`` (eqs. (7)-(8)). ``near_c`` changes no rate.
        """
        r = self.check_robot_state(r)
        L = self.layout
        p = L.positions(r)
        delta = p[..., 0, :] - p[..., 1, :]
        D = g.norm(delta)
        self.check_apart(r, separations=D)
        dx, dy, dz = np.moveaxis(delta, -1, 0)
        rho2 = dx * dx + dy * dy
        if np.any(rho2 <= (VERTICAL_TOL * D) ** 2):
            raise DegenerateInputError(
                "the Euclidean cluster Jacobian is undefined where one robot is straight above the "
                "other (gamma_c = +-pi/2, beta_c undefined); use QuaternionPair or DualQuaternionPair"
            )
        rho = np.sqrt(rho2)
        zero = np.zeros_like(dx)
        d_beta = np.stack([-dy, dx, zero], axis=-1) / rho2[..., None]
        d_gamma = np.stack([-dz * dx / rho, -dz * dy / rho, rho], axis=-1) / (D * D)[..., None]
        d_d = delta / (2.0 * D)[..., None]
        r_dot = as_array(r_dot, "r_dot", 8)
        v, w = L.positions(r_dot), L.yaws(r_dot)
        dd = v[..., 0, :] - v[..., 1, :]
        beta_dot = np.sum(d_beta * dd, axis=-1)
        return g.concat([0.5 * (v[..., 0, :] + v[..., 1, :]),
                         np.stack([beta_dot, np.sum(d_gamma * dd, axis=-1), np.sum(d_d * dd, axis=-1),
                                   w[..., 0] - beta_dot, w[..., 1] - beta_dot], axis=-1)])

    def robot_rate(self, c, c_dot, *, r=None):
        """Derivative of :meth:`inverse` at ``c`` along ``c_dot``; loses rank at a vertical segment.

        ``p1,2' = x_c' +- (d_c (beta_c' u_beta + gamma_c' u_gamma) + d_c' u)`` with ``u`` the
        unit segment of eqs. (4)-(5) and ``u_beta``, ``u_gamma`` its partials;
        ``theta_i' = beta_c' + phi_i'`` (eqs. (7)-(8)).
        """
        c = np.asarray(c, dtype=float)
        cd = as_array(c_dot, "c_dot", 8)
        u = segment_direction(c[..., 3], c[..., 4])
        u_b, u_g = _direction_partials(c[..., 3], c[..., 4])
        d = c[..., 5:6]
        half = d * u_b * cd[..., 3:4] + d * u_g * cd[..., 4:5] + u * cd[..., 5:6]
        v = np.stack([cd[..., 0:3] + half, cd[..., 0:3] - half], axis=-2)
        return self.layout.compose(v, np.stack([cd[..., 3] + cd[..., 6], cd[..., 3] + cd[..., 7]], axis=-1))

    def inverse_jacobian_at(self, c, *, r=None):
        """The dense derivative of :meth:`inverse` at ``c``, ``(..., 8, 8)``, in closed form
        (the columns of :meth:`robot_rate`, eqs. (4)-(8), written out: the cluster-space
        controller of seed 000 Fig. 2 applies this matrix every step, and building it from
        the rate map on the identity basis costs twice as much for one state). Rank 7 at a
        vertical segment."""
        if concrete(c) or isinstance(c, (list, tuple)):
            c = np.asarray(c, dtype=float)
        xp = namespace(c)
        u = segment_direction(c[..., 3], c[..., 4])
        u_b, u_g = _direction_partials(c[..., 3], c[..., 4])
        d = c[..., 5:6]
        zero = xp.zeros_like(c[..., 0])
        one = zero + 1.0
        rows = []
        for s in (1.0, -1.0):  # p1, p2 = x_c +- d_c u
            db, dg, du = s * d * u_b, s * d * u_g, s * u
            rows += [[one if i == j else zero for j in range(3)] + [db[..., i], dg[..., i], du[..., i], zero, zero]
                     for i in range(3)]
            # theta_1 = beta_c + phi_1, theta_2 = beta_c + phi_2
            rows.append([zero, zero, zero, one, zero, zero] + ([one, zero] if s > 0 else [zero, one]))
        return xp.stack([xp.stack(row, axis=-1) for row in rows], axis=-2)

    def special_sets(self):
        return sp.pair_sets("beta_c = atan2(-dx, dy) of eq. (4) is atan2(0, 0) with one robot straight above the "
                            "other: held at near_c's; its rate is undefined", jacobian="raises",
                            inverse_jacobian="rank-deficient")

    singularity_on_arrays = True
    #: :meth:`to_chart_arrays` runs on any array namespace.
    chart_on_arrays = True

    def inverse_jacobian_arrays(self, c, r):
        return self.inverse_jacobian_at(c, r=r)

    def to_chart(self, c, *, near_e=None, r=None):
        c = self.check_cluster_state(c)
        return self.to_chart_arrays(c, None if near_e is None else np.asarray(near_e, dtype=float))

    def to_chart_arrays(self, c, near_e=None, r=None):
        """:meth:`to_chart` of checked arrays of any namespace: ``c`` with ``beta_c``, ``phi_1``,
        ``phi_2`` unwrapped near ``near_e``'s (a new array)."""
        if near_e is None:
            return c.copy() if isinstance(c, np.ndarray) else c
        return map_entries(c, (3, 6, 7), lambda a, b: g.unwrap_near(c[..., a:b], near_e[..., a:b]))

    def from_chart(self, e, e_dot=None):
        e = self.check_cluster_state(e, "e")
        if e_dot is None:
            return e.copy()
        return e.copy(), as_array(e_dot, "e_dot", 8).copy()


class RobotSpace(Formation):
    """Robot space of two 4-DOF robots: ``c = r``; the description of seed 000 §3.1.

    Its monitoring conversion is the Euclidean forward kinematics, eqs. (1)-(8), as the
    seed's robot-space controller reports the formation: past ``|gamma_c| = pi/2`` it reads
    ``beta_c + pi``, ``pi - gamma_c`` (the ambiguity of §4.1).
    """

    name = "robot"
    key = "robot"
    variables = ROBOT_PAIR_VARIABLES
    chart_variables = EUCLIDEAN_VARIABLES
    _euclidean = EuclideanPair()

    def forward(self, r, *, near_c=None):
        r = self.check_robot_state(r)
        if near_c is not None:
            near_c = self.check_cluster_state(near_c, "near_c")
        return self.forward_arrays(r, near_c)

    def forward_arrays(self, r, near_c=None):
        """:meth:`forward` of checked arrays of any namespace (NumPy, JAX): ``r`` with its yaws
        unwrapped near ``near_c``'s (a new array)."""
        if near_c is None:
            return r.copy() if isinstance(r, np.ndarray) else r
        near_c = namespace(r).broadcast_to(near_c, np.broadcast_shapes(np.shape(r), np.shape(near_c)))
        r = namespace(r).broadcast_to(r, near_c.shape)
        return map_entries(r, self.layout.yaw_indices, lambda a, b: g.unwrap_near(r[..., a:b], near_c[..., a:b]))

    def inverse(self, c, *, near_r=None):
        return self.forward(c, near_c=near_r)

    def cluster_rate(self, r, r_dot, *, near_c=None):
        """``c_dot = r_dot``: the identity (seed 000 §3.1)."""
        r = self.check_robot_state(r)
        r_dot = as_array(r_dot, "r_dot", 8)
        return np.broadcast_to(r_dot, np.broadcast_shapes(r.shape, r_dot.shape)).copy()

    def robot_rate(self, c, c_dot, *, r=None):
        """``r_dot = c_dot``: the identity."""
        c = self.check_robot_state(c, "c")
        c_dot = as_array(c_dot, "c_dot", 8)
        return np.broadcast_to(c_dot, np.broadcast_shapes(c.shape, c_dot.shape)).copy()

    def inverse_jacobian_at(self, c, *, r=None):
        """The identity (robot space is its own cluster space), ``(..., 8, 8)``."""
        if concrete(c) or isinstance(c, (list, tuple)):
            c = self.check_robot_state(c, "c")
            return np.broadcast_to(np.eye(8), c.shape[:-1] + (8, 8)).copy()
        xp = namespace(c)
        return xp.broadcast_to(xp.eye(8), c.shape[:-1] + (8, 8))

    def length_scale(self, r):
        return namespace(r).ones(np.shape(r)[:-1])

    singularity_on_arrays = True
    chart_on_arrays = True

    def inverse_jacobian_arrays(self, c, r):
        return self.inverse_jacobian_at(c, r=r)

    def special_sets(self):
        return sp.pair_sets("the Euclidean chart of eqs. (1)-(8) is singular here; the robot space is not")

    def to_chart(self, c, *, near_e=None, r=None):
        return self._euclidean.to_chart(self._euclidean.forward(c), near_e=near_e)

    def to_chart_arrays(self, c, near_e=None, r=None):
        """:meth:`to_chart` of checked arrays of any namespace (robots apart)."""
        E = self._euclidean
        return E.to_chart_arrays(E.forward_arrays(c), near_e)

    def from_chart(self, e, e_dot=None):
        E = self._euclidean
        e = E.check_cluster_state(e, "e")
        r = E.inverse(e)
        if e_dot is None:
            return r
        # the dense matrix (not the rate map) keeps the rounding the reference runs were recorded with
        return r, np.einsum("...ij,...j->...i", E.inverse_jacobian_at(e), as_array(e_dot, "e_dot", 8))
