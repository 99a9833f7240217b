"""Euclidean cluster space of two 4-DOF robots, seed 000 eqs. (1)-(8), and the robot space.

Formations layer. ``EuclideanPair`` is the minimal (8-variable) baseline of Mas & Kitts:
``c = (x_c, y_c, z_c, beta_c, gamma_c, d_c, phi_1, phi_2)``; it is singular where the
segment between the robots is vertical (``|gamma_c| = pi/2``: ``beta_c`` undefined) and
where the robots coincide. ``RobotSpace`` is the identity description used by the
robot-space controller of seed 000 §3.1.
"""

from __future__ import annotations

import numpy as np

from ..algebra.validate import as_array
from ..errors import DegenerateInputError
from . import geometry as g
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
    cb, sb, cg, sg = np.cos(beta), np.sin(beta), np.cos(gamma), np.sin(gamma)
    return np.stack([-sb * cg, cb * cg, sg], axis=-1)


def _direction_partials(beta, gamma):
    cb, sb, cg, sg = np.cos(beta), np.sin(beta), np.cos(gamma), np.sin(gamma)
    u_b = np.stack([-cb * cg, -sb * cg, np.zeros_like(cb)], axis=-1)
    u_g = np.stack([sb * sg, -cb * sg, cg], axis=-1)
    return u_b, u_g


class EuclideanPair(Formation):
    """Seed 000 eqs. (1)-(8): position, yaw, pitch, half-separation and relative yaws.

    Eq. (6) is printed ``sqrt(dx^2 + dy^2 + dz^2/2)``; ``d_c`` is *half the distance*
    (text and Fig. 1), i.e. ``sqrt(dx^2 + dy^2 + dz^2) / 2`` (``docs/derivations.md``).
    ``gamma_c`` lies in ``[-pi/2, pi/2]`` (the range of eq. (5)); a pitch beyond it is
    read as ``beta_c + pi`` and ``pi - gamma_c``, the ambiguity of seed 000 §4.1.
    """

    name = "euclidean"
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
        p1, p2 = r[..., 0:3], r[..., 4:7]
        delta = p1 - p2
        D = self._check_separation(delta)
        rho = np.hypot(delta[..., 0], delta[..., 1])
        c = np.empty(r.shape[:-1] + (8,))
        c[..., 0:3] = 0.5 * (p1 + p2)  # seed 000 eqs. (1)-(3)
        beta = np.arctan2(-delta[..., 0], delta[..., 1])  # eq. (4)
        c[..., 4] = np.arctan2(delta[..., 2], rho)  # eq. (5)
        c[..., 5] = 0.5 * D  # eq. (6), corrected
        if near_c is not None:
            near_c = self.check_cluster_state(near_c, "near_c")
            beta = np.where(rho <= VERTICAL_TOL * D, near_c[..., 3], g.unwrap_near(beta, near_c[..., 3]))
            c[..., 6] = g.unwrap_near(r[..., 3] - beta, near_c[..., 6])  # eqs. (7)-(8)
            c[..., 7] = g.unwrap_near(r[..., 7] - beta, near_c[..., 7])
        else:
            c[..., 6] = g.wrap(r[..., 3] - beta)
            c[..., 7] = g.wrap(r[..., 7] - beta)
        c[..., 3] = beta
        return c

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
        r = np.empty(c.shape[:-1] + (8,))
        r[..., 0:3] = c[..., 0:3] + half
        r[..., 4:7] = c[..., 0:3] - half
        r[..., 3] = c[..., 6] + c[..., 3]
        r[..., 7] = c[..., 7] + c[..., 3]
        if near_r is not None:
            near_r = self.check_robot_state(near_r, "near_r")
            r[..., 3] = g.unwrap_near(r[..., 3], near_r[..., 3])
            r[..., 7] = g.unwrap_near(r[..., 7], near_r[..., 7])
        return r

    def jacobian(self, r, *, near_c=None):
        """The 8 x 8 cluster Jacobian; undefined (raises) at a vertical segment."""
        r = self.check_robot_state(r)
        delta = r[..., 0:3] - r[..., 4:7]
        D = self._check_separation(delta)
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
        J = np.zeros(r.shape[:-1] + (8, 8))
        eye = np.eye(3)
        J[..., 0:3, 0:3] = 0.5 * eye
        J[..., 0:3, 4:7] = 0.5 * eye
        for row, grad in ((3, d_beta), (4, d_gamma), (5, d_d)):
            J[..., row, 0:3] = grad
            J[..., row, 4:7] = -grad
        for row, col in ((6, 3), (7, 7)):
            J[..., row, 0:3] = -d_beta
            J[..., row, 4:7] = d_beta
            J[..., row, col] = 1.0
        return J

    def inverse_jacobian_at(self, c, *, r=None):
        """Derivative of :meth:`inverse` at ``c``, shape ``(..., 8, 8)``; rank 7 at a vertical segment."""
        c = np.asarray(c, dtype=float)
        u = segment_direction(c[..., 3], c[..., 4])
        u_b, u_g = _direction_partials(c[..., 3], c[..., 4])
        d = c[..., 5:6]
        Ji = np.zeros(c.shape[:-1] + (8, 8))
        eye = np.eye(3)
        for rows, s in ((slice(0, 3), 1.0), (slice(4, 7), -1.0)):
            Ji[..., rows, 0:3] = eye
            Ji[..., rows, 3] = s * d * u_b
            Ji[..., rows, 4] = s * d * u_g
            Ji[..., rows, 5] = s * u
        Ji[..., 3, 3] = Ji[..., 3, 6] = 1.0
        Ji[..., 7, 3] = Ji[..., 7, 7] = 1.0
        return Ji

    def to_chart(self, c, *, near_e=None, r=None):
        c = self.check_cluster_state(c)
        if near_e is None:
            return c.copy()
        near_e = np.asarray(near_e, dtype=float)
        e = c.copy()
        for i in (3, 6, 7):
            e[..., i] = g.unwrap_near(c[..., i], near_e[..., i])
        return e

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
    variables = ROBOT_PAIR_VARIABLES
    chart_variables = EUCLIDEAN_VARIABLES
    _euclidean = EuclideanPair()

    def forward(self, r, *, near_c=None):
        r = self.check_robot_state(r).copy()
        if near_c is not None:
            near_c = self.check_cluster_state(near_c, "near_c")
            for i in (3, 7):
                r[..., i] = g.unwrap_near(r[..., i], near_c[..., i])
        return r

    def inverse(self, c, *, near_r=None):
        return self.forward(c, near_c=near_r)

    def jacobian(self, r, *, near_c=None):
        r = self.check_robot_state(r)
        return np.broadcast_to(np.eye(8), r.shape[:-1] + (8, 8)).copy()

    def inverse_jacobian_at(self, c, *, r=None):
        return self.jacobian(c)

    def length_scale(self, r):
        return np.ones(np.shape(r)[:-1])

    def to_chart(self, c, *, near_e=None, r=None):
        return self._euclidean.to_chart(self._euclidean.forward(c), near_e=near_e)

    def from_chart(self, e, e_dot=None):
        E = self._euclidean
        e = E.check_cluster_state(e, "e")
        r = E.inverse(e)
        if e_dot is None:
            return r
        return r, np.einsum("...ij,...j->...i", E.inverse_jacobian_at(e), as_array(e_dot, "e_dot", 8))
