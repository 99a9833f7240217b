"""Descriptions of a ground robot (UGV) and a quadrotor (UAV) formation, seed 001 §4.1-4.2.

Formations layer. Robot state ``r = (x_p, y_p, z_p, x_b, y_b, z_b)``: the Pioneer's
control point and the Bebop's position (yaws are controlled outside the formation, seed
001 §4.3.3). Three descriptions, all with the cluster point at the UGV:

* ``UgvUavSpherical`` (Rabelo et al.), eqs. (4.1)-(4.12): ``(x_c, y_c, z_c, rho_c,
  alpha_c, beta_c)``; singular with the UAV straight above the UGV (``alpha_c`` undefined).
* ``UgvUavRestricted`` (Ernandes-Neto et al.), eqs. (4.13)-(4.24): ``(x_f, y_f, z_f, rho_f,
  alpha_f, beta_f)`` with ``alpha_f = asin(dx/rho)``, ``beta_f = asin(dy/rho)``; regular
  over the UGV, but only ``0 <= alpha_f, beta_f <= 45 deg`` is used (the UAV above the
  platform); other states are refused with ``UnreachableError``.
* ``UgvUavQuaternion`` (Marciano), eqs. (4.25)-(4.41): ``(x_c[3], q_c[4], d_c[3])`` with
  ``d_c = (d, 0, 0)``, 10 values; the 6 x 10 inverse Jacobian (4.39). The twist of
  ``q_c`` is taken from ``near_c``, as for :class:`QuaternionPair`.

Their common operator chart (``to_chart``, ``chart_variables``) is the spherical variables.
"""

from __future__ import annotations

import math

import numpy as np

from ..algebra.validate import as_array, as_unit_quaternion
from ..algebra.operators import jac_qrotate_quaternion, jac_qrotate_vector, qminus, skew
from ..errors import DegenerateInputError, InvalidInputError, UnreachableError
from . import geometry as g
from .base import Formation, Variable, quaternion_variables

__all__ = ["UgvUavSpherical", "UgvUavRestricted", "UgvUavQuaternion", "UGV_UAV_VARIABLES",
           "SPHERICAL_VARIABLES"]

UGV_UAV_VARIABLES = (
    Variable("x_p", "m", "position"), Variable("y_p", "m", "position"), Variable("z_p", "m", "position"),
    Variable("x_b", "m", "position"), Variable("y_b", "m", "position"), Variable("z_b", "m", "position"),
)
SPHERICAL_VARIABLES = (
    Variable("x_c", "m", "position"), Variable("y_c", "m", "position"), Variable("z_c", "m", "position"),
    Variable("rho_c", "m", "length"), Variable("alpha_c", "rad", "angle"), Variable("beta_c", "rad", "angle"),
)
#: Smallest vertical fraction of the segment the restricted inverse Jacobian divides by.
W_MIN = 1e-3
#: Below this ratio of horizontal to full separation, alpha_c of eq. (4.5) is undefined.
OVERHEAD_TOL = 1e-12


def _jacobian_from_gradients(grads):
    """``[[I, 0], [-g_k, g_k]]``: the cluster point is the UGV; rows 3-5 depend on ``x_b - x_p``."""
    J = np.zeros(grads[0].shape[:-1] + (6, 6))
    J[..., 0:3, 0:3] = np.eye(3)
    for row, gr in zip((3, 4, 5), grads, strict=True):
        J[..., row, 0:3] = -gr
        J[..., row, 3:6] = gr
    return J


class _UgvUav(Formation):
    robot_variables = UGV_UAV_VARIABLES
    chart_variables = SPHERICAL_VARIABLES

    def outside(self, r):
        """Where the robot state ``r`` (..., 6) is outside the description: a bool array (...)."""
        return np.zeros(np.shape(r)[:-1], dtype=bool)

    def length_scale(self, r):
        r = np.asarray(r)
        return np.linalg.norm(r[..., 3:6] - r[..., 0:3], axis=-1)

    def _delta(self, r, name="r"):
        r = self.check_robot_state(r, name)
        delta = r[..., 3:6] - r[..., 0:3]
        self._check_separation(delta, name)
        return r, delta

    def to_chart(self, c, *, near_e=None, r=None):
        return UgvUavSpherical().forward(self.inverse(c) if r is None else r, near_c=near_e)

    def align(self, r, r_ref):
        return np.asarray(r, dtype=float)


class UgvUavSpherical(_UgvUav):
    """Eqs. (4.1)-(4.12). ``alpha_c = atan2(dy, dx)`` (the printed arctan of a ratio loses
    the quadrant), ``beta_c = atan2(dz, |d_xy|)``."""

    name = "spherical"
    variables = SPHERICAL_VARIABLES

    def forward(self, r, *, near_c=None):
        r, d = self._delta(r)
        rho_h = np.hypot(d[..., 0], d[..., 1])
        c = np.empty(r.shape[:-1] + (6,))
        c[..., 0:3] = r[..., 0:3]  # (4.1)-(4.3)
        c[..., 3] = np.linalg.norm(d, axis=-1)  # (4.4)
        alpha = np.arctan2(d[..., 1], d[..., 0])  # (4.5)
        if near_c is not None:
            near_c = as_array(near_c, "near_c", 6)
            alpha = np.where(rho_h <= OVERHEAD_TOL * c[..., 3], near_c[..., 4], g.unwrap_near(alpha, near_c[..., 4]))
        c[..., 4] = alpha
        c[..., 5] = np.arctan2(d[..., 2], rho_h)  # (4.6)
        return c

    def inverse(self, c, *, near_r=None):
        c = self.check_cluster_state(c)
        if np.any(c[..., 3] <= 0):
            raise DegenerateInputError(f"rho_c must be positive, got {float(np.min(c[..., 3]))!r}")
        a, b = c[..., 4], c[..., 5]
        r = np.empty(c.shape[:-1] + (6,))
        r[..., 0:3] = c[..., 0:3]  # (4.7)-(4.9)
        r[..., 3] = c[..., 0] + c[..., 3] * np.cos(a) * np.cos(b)  # (4.10)
        r[..., 4] = c[..., 1] + c[..., 3] * np.sin(a) * np.cos(b)  # (4.11)
        r[..., 5] = c[..., 2] + c[..., 3] * np.sin(b)  # (4.12)
        return r

    def jacobian(self, r, *, near_c=None):
        """6 x 6; undefined (raises) with the UAV straight above or below the UGV."""
        r, d = self._delta(r)
        dx, dy, dz = np.moveaxis(d, -1, 0)
        h2 = dx * dx + dy * dy
        D = np.sqrt(h2 + dz * dz)
        if np.any(h2 <= (OVERHEAD_TOL * D) ** 2):
            raise DegenerateInputError(
                "the spherical formation's Jacobian is undefined with the UAV straight above the UGV "
                "(alpha_c undefined, Marciano 2021 §4.1.1); use the quaternion description"
            )
        h = np.sqrt(h2)
        z = np.zeros_like(dx)
        grads = [d / D[..., None], np.stack([-dy, dx, z], -1) / h2[..., None],
                 np.stack([-dz * dx / h, -dz * dy / h, h], -1) / (D * D)[..., None]]
        return _jacobian_from_gradients(grads)

    def inverse_jacobian_at(self, c, *, r=None):
        """Derivative of (4.7)-(4.12); rank 5 with the UAV overhead (``cos beta_c = 0``)."""
        c = np.asarray(c, dtype=float)
        rho, a, b = c[..., 3], c[..., 4], c[..., 5]
        ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
        Ji = np.zeros(c.shape[:-1] + (6, 6))
        Ji[..., 0:3, 0:3] = np.eye(3)
        Ji[..., 3:6, 0:3] = np.eye(3)
        Ji[..., 3:6, 3] = np.stack([ca * cb, sa * cb, sb], -1)
        Ji[..., 3:6, 4] = rho[..., None] * np.stack([-sa * cb, ca * cb, 0 * cb], -1)
        Ji[..., 3:6, 5] = rho[..., None] * np.stack([-ca * sb, -sa * sb, cb], -1)
        return Ji

    def to_chart(self, c, *, near_e=None, r=None):
        c = self.check_cluster_state(c)
        if near_e is None:
            return c.copy()
        e = c.copy()
        e[..., 4] = g.unwrap_near(c[..., 4], np.asarray(near_e, dtype=float)[..., 4])
        return e

    def from_chart(self, e, e_dot=None):
        e = self.check_cluster_state(e, "e")
        if e_dot is None:
            return e.copy()
        return e.copy(), as_array(e_dot, "e_dot", 6).copy()


class UgvUavRestricted(_UgvUav):
    """Eqs. (4.13)-(4.24), with the operating range ``0 <= alpha_f, beta_f <= 45 deg``.

    The description exists only with the UAV at or above the platform: (4.24) takes the
    positive root, so a UAV ``h`` below would come back ``h`` above (``forward`` reads only
    ``dx / rho`` and ``dy / rho``, eqs. (4.17)-(4.18)). ``forward`` and ``inverse`` refuse
    such states, and angles more than ``tolerance_deg`` outside the operating range (the
    measurement noise about the range's edge at the overhead pose ``alpha_f = beta_f = 0``),
    with :class:`~quatform.errors.UnreachableError`; ``from_euclidean`` (references) holds
    them to the range itself.

    Parameters
    ----------
    range_deg : tuple of float
        Allowed range of ``alpha_f`` and ``beta_f`` (seed 001 §4.1.2: 0 to 45 deg).
    tolerance_deg : float
        How far outside the range measured states are still accepted, deg (1).
    """

    name = "restricted"
    variables = (
        Variable("x_f", "m", "position"), Variable("y_f", "m", "position"), Variable("z_f", "m", "position"),
        Variable("rho_f", "m", "length"), Variable("alpha_f", "rad", "angle"), Variable("beta_f", "rad", "angle"),
    )

    def __init__(self, range_deg=(0.0, 45.0), tolerance_deg=1.0):
        lo, hi = (float(x) for x in range_deg)
        if not (-90.0 <= lo < hi <= 90.0) or not (0.0 <= tolerance_deg <= 10.0):
            raise InvalidInputError(
                f"restricted description: range_deg = {range_deg!r} must satisfy -90 <= low < high <= 90 and "
                f"tolerance_deg = {tolerance_deg!r} must be in [0, 10]"
            )
        self.range = (math.radians(lo), math.radians(hi))
        self.tolerance = math.radians(tolerance_deg)

    def _angles_out(self, c, tol):
        lo, hi = self.range
        return [(name, (c[..., i] < lo - tol) | (c[..., i] > hi + tol)) for i, name in ((4, "alpha_f"), (5, "beta_f"))]

    @staticmethod
    def _formulas(r):
        """Eqs. (4.13)-(4.18) without checks, and ``z_b - z_p``: ``(c (..., 6), dz (...))``."""
        d = r[..., 3:6] - r[..., 0:3]
        rho = np.linalg.norm(d, axis=-1)
        c = np.empty(r.shape[:-1] + (6,))
        c[..., 0:3] = r[..., 0:3]  # (4.13)-(4.15)
        c[..., 3] = rho  # (4.16)
        with np.errstate(invalid="ignore", divide="ignore"):
            c[..., 4] = np.arcsin(np.clip(d[..., 0] / rho, -1, 1))  # (4.17)
            c[..., 5] = np.arcsin(np.clip(d[..., 1] / rho, -1, 1))  # (4.18)
        return c, d[..., 2]

    def outside(self, r):
        """Where ``r`` is outside the description: the UAV below the platform, or an angle more
        than ``tolerance_deg`` outside the range; a bool array (...). Raises nothing."""
        c, dz = self._formulas(np.asarray(r, dtype=float))
        out = dz < 0
        for _, bad in self._angles_out(c, self.tolerance):
            out |= bad
        return out

    @staticmethod
    def _refuse_below(dz, what, fix):
        below = dz < 0
        if np.any(below):
            idx = tuple(int(i) for i in np.argwhere(np.atleast_1d(below))[0])
            h = float(np.atleast_1d(dz)[idx])
            at = f" at index {idx}" if np.ndim(dz) else ""
            raise UnreachableError(
                f"{what}: z_b - z_p = {h:.6g} m{at}: the UAV is below the platform, which the "
                f"restricted description cannot express (eq. (4.24) would put it {-h:.6g} m above; Marciano 2021 "
                f"§4.1.2); {fix}"
            )

    def check_reachable(self, c, what="state", tol=1e-9):
        """Raise UnreachableError if ``alpha_f`` or ``beta_f`` leaves the operating range by
        more than ``tol`` rad, or (4.24) has no real root (``sin^2 alpha_f + sin^2 beta_f > 1``)."""
        lo, hi = self.range
        for name, bad in self._angles_out(c, tol):
            if np.any(bad):
                val = float(np.asarray(c[..., 4 if name == "alpha_f" else 5])[bad].flat[0])
                raise UnreachableError(
                    f"{what}: {name} = {math.degrees(val):.1f} deg is outside the restricted description's "
                    f"range [{math.degrees(lo):.0f}, {math.degrees(hi):.0f}] deg (Marciano 2021 §4.1.2: the UAV must "
                    "be above the platform, ahead and to the left within 45 deg); use the quaternion description"
                )
        w2 = 1 - np.sin(c[..., 4]) ** 2 - np.sin(c[..., 5]) ** 2
        if np.any(w2 < -1e-12):
            raise UnreachableError(
                f"{what}: sin^2 alpha_f + sin^2 beta_f = {float(1 - np.min(w2)):.6g} > 1: eq. (4.24) has no real "
                "root (Marciano 2021 §4.1.2); use the quaternion description"
            )

    def _expressible(self, r, name="r"):
        """The one check of a robot state that :meth:`forward`, :meth:`jacobian` and so
        :meth:`inverse_jacobian` and :meth:`singularity_measure` share: refuse the UAV below
        the platform and angles more than ``tolerance_deg`` outside the range
        (UnreachableError, as :meth:`outside` marks them). Returns ``(r, delta, c)``."""
        r, d = self._delta(r, name)
        c, dz = self._formulas(r)  # (4.13)-(4.18)
        self._refuse_below(dz, name, "use the spherical or quaternion description")
        self.check_reachable(c, name, self.tolerance)
        return r, d, c

    def _expressible_cluster(self, c, name="cluster state"):
        """The check of a cluster state that :meth:`inverse` and :meth:`inverse_jacobian_at`
        share: ``rho_f > 0`` and the angles within the range and its tolerance."""
        c = self.check_cluster_state(c, "c")
        if np.any(c[..., 3] <= 0):
            raise DegenerateInputError(f"rho_f must be positive, got {float(np.min(c[..., 3]))!r}")
        self.check_reachable(c, name, self.tolerance)
        return c

    def forward(self, r, *, near_c=None):
        return self._expressible(r)[2]

    def inverse(self, c, *, near_r=None):
        c = self._expressible_cluster(c)
        sa, sb = np.sin(c[..., 4]), np.sin(c[..., 5])
        r = np.empty(c.shape[:-1] + (6,))
        r[..., 0:3] = c[..., 0:3]  # (4.19)-(4.21)
        r[..., 3] = c[..., 0] + c[..., 3] * sa  # (4.22)
        r[..., 4] = c[..., 1] + c[..., 3] * sb  # (4.23)
        r[..., 5] = c[..., 2] + c[..., 3] * np.sqrt(np.maximum(0.0, 1 - sa * sa - sb * sb))  # (4.24)
        return r

    def jacobian(self, r, *, near_c=None):
        """6 x 6; singular where ``sin^2 alpha_f + sin^2 beta_f = 1`` (UAV at platform level).
        Refuses what :meth:`forward` refuses (UnreachableError: the UAV below the platform,
        angles outside the range): there the description, so its rate, does not exist."""
        r, d, _ = self._expressible(r)
        rho = np.linalg.norm(d, axis=-1)
        u = d / rho[..., None]
        cos_a2, cos_b2 = 1 - u[..., 0] ** 2, 1 - u[..., 1] ** 2
        if np.any(np.minimum(cos_a2, cos_b2) < 1e-24):
            raise DegenerateInputError(
                "the restricted formation's Jacobian is undefined with the UAV along the x or y axis "
                "through the UGV (alpha_f or beta_f = +-90 deg, asin at its end)"
            )
        dd = np.eye(3) - u[..., :, None] * u[..., None, :]  # d u / d delta * rho
        return _jacobian_from_gradients([u, dd[..., 0, :] / (rho * np.sqrt(cos_a2))[..., None],
                                         dd[..., 1, :] / (rho * np.sqrt(cos_b2))[..., None]])

    def singularity_measure(self, r, *, near_c=None):
        """As :meth:`Formation.singularity_measure`; refuses what :meth:`forward` refuses, naming
        the state as given (not the normalised one the measure is taken on)."""
        self._expressible(r)
        return super().singularity_measure(r, near_c=near_c)

    def inverse_jacobian_at(self, c, *, r=None):
        """Derivative of eqs. (4.19)-(4.24) at ``c`` (..., 6), shape (..., 6, 6); refuses what
        :meth:`inverse` refuses, and ``r`` (if given) where :meth:`forward` refuses it."""
        c = self._expressible_cluster(c)
        if r is not None:
            self._expressible(r)
        rho, a, b = c[..., 3], c[..., 4], c[..., 5]
        sa, ca, sb, cb = np.sin(a), np.cos(a), np.sin(b), np.cos(b)
        # (4.24)'s root: its derivative is infinite at platform level; clipped at W_MIN
        w = np.sqrt(np.maximum(W_MIN ** 2, 1 - sa * sa - sb * sb))
        Ji = np.zeros(c.shape[:-1] + (6, 6))
        Ji[..., 0:3, 0:3] = np.eye(3)
        Ji[..., 3:6, 0:3] = np.eye(3)
        Ji[..., 3:6, 3] = np.stack([sa, sb, w], -1)
        Ji[..., 3:6, 4] = rho[..., None] * np.stack([ca, 0 * ca, -sa * ca / w], -1)
        Ji[..., 3:6, 5] = rho[..., None] * np.stack([0 * cb, cb, -sb * cb / w], -1)
        return Ji

    def from_chart(self, e, e_dot=None):
        S = UgvUavSpherical()
        r = S.inverse(e)
        c, dz = self._formulas(r)
        self._refuse_below(dz, "reference", "use the quaternion description")
        self.check_reachable(c, "reference")
        if e_dot is None:
            return c
        r_dot = np.einsum("...ij,...j->...i", S.inverse_jacobian_at(e), as_array(e_dot, "e_dot", 6))
        return c, np.einsum("...ij,...j->...i", self.jacobian(r), r_dot)


class UgvUavQuaternion(_UgvUav):
    """Eqs. (4.25)-(4.41): cluster point at the UGV, ``q_c`` on the segment, ``d_c = (d, 0, 0)``."""

    name = "quaternion"
    variables = (
        Variable("x_c", "m", "position"), Variable("y_c", "m", "position"), Variable("z_c", "m", "position"),
        *quaternion_variables("q_c"),
        Variable("d_c_x", "m", "length"), Variable("d_c_y", "m", "length"), Variable("d_c_z", "m", "length"),
    )

    def check_cluster_state(self, c, name="c"):
        c = super().check_cluster_state(c, name)
        as_unit_quaternion(c[..., 3:7], f"{name}[q_c]")
        return c

    def forward(self, r, *, near_c=None):
        r, d = self._delta(r)
        D = np.linalg.norm(d, axis=-1)
        u = d / D[..., None]
        if near_c is None:  # eqs. (4.26), (4.28), (4.29): minimal rotation from i
            qh = np.array([1.0, 0.0, 0.0, 0.0])
        else:
            qh = self.check_cluster_state(near_c, "near_c")[..., 3:7]
        qc = g.mul(g.swing(g.x_axis(qh), u, g.z_axis(qh)), qh)
        c = np.zeros(r.shape[:-1] + (10,))
        c[..., 0:3] = r[..., 0:3]  # (4.25)
        c[..., 3:7] = g.closest_sign(qc, qh)
        c[..., 7] = D  # (4.27)
        return c

    def inverse(self, c, *, near_r=None):
        c = self.check_cluster_state(c)
        qc = c[..., 3:7] / np.linalg.norm(c[..., 3:7], axis=-1, keepdims=True)
        if np.any(np.linalg.norm(c[..., 7:10], axis=-1) <= 0):
            raise DegenerateInputError("d_c must be nonzero (the robots would coincide)")
        r = np.empty(c.shape[:-1] + (6,))
        r[..., 0:3] = c[..., 0:3]  # (4.30)
        r[..., 3:6] = c[..., 0:3] + g.rotate(qc, c[..., 7:10])  # (4.31)
        return r

    def jacobian(self, r, *, near_c=None):
        """``c_dot = J r_dot`` (10 x 6) for the forward map near ``near_c`` (no twist rate)."""
        c = self.forward(r, near_c=near_c)
        u = g.x_axis(c[..., 3:7])
        D = c[..., 7]
        dq = 0.5 * qminus(c[..., 3:7])[..., :, 1:] @ (skew(u) / D[..., None, None])
        J = np.zeros(c.shape[:-1] + (10, 6))
        J[..., 0:3, 0:3] = np.eye(3)
        J[..., 3:7, 0:3] = -dq
        J[..., 3:7, 3:6] = dq
        J[..., 7, 0:3] = -u
        J[..., 7, 3:6] = u
        return J

    def inverse_jacobian_at(self, c, *, r=None):
        """Eq. (4.39): ``[[I, 0, 0], [I, d(q d q*)/dq (4.40), d(q d q*)/dd (4.41)]]``, 6 x 10."""
        c = np.asarray(c, dtype=float)
        Ji = np.zeros(c.shape[:-1] + (6, 10))
        Ji[..., 0:3, 0:3] = np.eye(3)
        Ji[..., 3:6, 0:3] = np.eye(3)
        Ji[..., 3:6, 3:7] = jac_qrotate_quaternion(c[..., 3:7], c[..., 7:10])
        Ji[..., 3:6, 7:10] = jac_qrotate_vector(c[..., 3:7])
        return Ji

    def from_chart(self, e, e_dot=None):
        """``q_c = q_z(alpha) q_y(-beta)`` (x axis along the segment, no twist): continuous in ``e``."""
        e = UgvUavSpherical().check_cluster_state(e, "e")
        qz, qy = g.q_yaw(e[..., 4]), g.q_pitch_y(-e[..., 5])
        c = np.zeros(e.shape[:-1] + (10,))
        c[..., 0:3] = e[..., 0:3]
        c[..., 3:7] = g.mul(qz, qy)
        c[..., 7] = e[..., 3]
        if e_dot is None:
            return c
        ed = as_array(e_dot, "e_dot", 6)
        cd = np.zeros_like(c)
        cd[..., 0:3] = ed[..., 0:3]
        cd[..., 3:7] = ed[..., 4, None] * 0.5 * g.mul(np.array([0.0, 0, 0, 1]), g.mul(qz, qy)) + g.mul(
            qz, -ed[..., 5, None] * 0.5 * g.mul(qy, np.array([0.0, 0.0, 1.0, 0.0])))
        cd[..., 7] = ed[..., 3]
        return c, cd
