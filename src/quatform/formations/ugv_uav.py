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

from ..algebra.kernels import array_namespace as namespace
from ..algebra.kernels import as_floats, common_namespace, concrete, dot_last
from ..algebra.validate import as_array, as_unit_quaternion
from ..errors import DegenerateInputError, InvalidInputError, UnreachableError
from . import geometry as g
from . import special_sets as sp
from .base import MAX_MAGNITUDE, Formation, Variable, quaternion_variables
from .layout import RobotLayout

__all__ = ["UgvUavSpherical", "UgvUavRestricted", "UgvUavQuaternion", "UGV_UAV_VARIABLES", "UGV_UAV_LAYOUT",
           "UGV_POINT", "UAV_POINT", "SPHERICAL_VARIABLES"]

#: The UGV's control point and the UAV's position (yaws are controlled outside the formation).
UGV_UAV_LAYOUT = RobotLayout(("xyz", "xyz"), labels=("_p", "_b"), display_names=("UGV", "UAV"))
UGV_UAV_VARIABLES = UGV_UAV_LAYOUT.variables
#: The UGV's and the UAV's points in the robot state ``r`` (and its rates).
UGV_POINT, UAV_POINT = (UGV_UAV_LAYOUT.slice(i) for i in range(UGV_UAV_LAYOUT.n))
SPHERICAL_VARIABLES = (
    Variable("x_c", "m", "position"), Variable("y_c", "m", "position"), Variable("z_c", "m", "position"),
    Variable("rho_c", "m", "length"), Variable("alpha_c", "rad", "angle"), Variable("beta_c", "rad", "angle"),
)
#: Smallest vertical fraction of the segment the restricted inverse Jacobian divides by.
W_MIN = 1e-3
#: Below this ratio of horizontal to full separation, alpha_c of eq. (4.5) is undefined.
OVERHEAD_TOL = 1e-12


def _rate_from_gradients(grads, v):
    """``c_dot`` of ``c = (x_p, f_1..3(x_b - x_p))``: ``(v_p, g_k . (v_b - v_p))``, the rows
    ``[[I, 0], [-g_k, g_k]]`` of the Jacobian applied to the point velocities ``v (..., 2, 3)``."""
    dv = v[..., 1, :] - v[..., 0, :]
    return g.concat([v[..., 0, :], np.stack([np.sum(gr * dv, axis=-1) for gr in grads], axis=-1)])


class _UgvUav(Formation):
    layout = UGV_UAV_LAYOUT
    chart_variables = SPHERICAL_VARIABLES

    def outside(self, r):
        """``~reachable(r)`` (the name the UGV-UAV controller and simulator use)."""
        return ~self.reachable(r)

    def length_scale(self, r):
        """The UGV-UAV separation ``rho``, m, shape ``(...)``."""
        return 2.0 * super().length_scale(r)

    def _delta(self, r, name="r"):
        """Checked ``r``, the UGV point ``x_p`` and ``delta = x_b - x_p``, each ``(..., 3)``."""
        r = self.check_robot_state(r, name)
        p = self.layout.positions(r)
        d = p[..., 1, :] - p[..., 0, :]
        self.check_apart(r, name, separations=g.norm(d))
        return r, p[..., 0, :], d

    def _robots(self, x_p, x_b):
        """Robot state (or rate) of the UGV point and the UAV position (any namespace)."""
        if concrete(x_p) and concrete(x_b):
            return self.layout.compose(np.stack(np.broadcast_arrays(x_p, x_b), axis=-2))
        xp = common_namespace(x_p, x_b)
        return xp.concatenate(xp.broadcast_arrays(x_p, x_b), axis=-1)  # the layout (xyz, xyz): x_p then x_b

    def to_chart(self, c, *, near_e=None, r=None):
        return UgvUavSpherical().forward(self.inverse(c) if r is None else r, near_c=near_e)


class UgvUavSpherical(_UgvUav):
    """Eqs. (4.1)-(4.12). ``alpha_c = atan2(dy, dx)`` (the printed arctan of a ratio loses
    the quadrant), ``beta_c = atan2(dz, |d_xy|)``."""

    name = "spherical"
    key = "ugv-uav-spherical"
    variables = SPHERICAL_VARIABLES

    def forward(self, r, *, near_c=None):
        r, _, _ = self._delta(r)
        return self.forward_arrays(r, None if near_c is None else as_array(near_c, "near_c", 6))

    def forward_arrays(self, r, near_c=None):
        xp = namespace(r)
        p = self.layout.positions(r) if xp is np else r.reshape(r.shape[:-1] + (2, 3))
        x_p, d = p[..., 0, :], p[..., 1, :] - p[..., 0, :]
        rho_h = xp.hypot(d[..., 0], d[..., 1])
        rho = xp.linalg.norm(d, axis=-1)  # (4.4)
        alpha = xp.arctan2(d[..., 1], d[..., 0])  # (4.5)
        if near_c is not None:
            alpha = xp.where(rho_h <= OVERHEAD_TOL * rho, near_c[..., 4], g.unwrap_near(alpha, near_c[..., 4]))
        # (4.1)-(4.3), (4.4), (4.5), (4.6)
        return g.concat([x_p, xp.stack(xp.broadcast_arrays(rho, alpha, xp.arctan2(d[..., 2], rho_h)), axis=-1)])

    def inverse(self, c, *, near_r=None):
        c = self.check_cluster_state(c)
        if np.any(c[..., 3] <= 0):
            raise DegenerateInputError(f"rho_c must be positive, got {float(np.min(c[..., 3]))!r}")
        a, b = c[..., 4], c[..., 5]
        x_b = np.stack([c[..., 0] + c[..., 3] * np.cos(a) * np.cos(b),  # (4.10)
                        c[..., 1] + c[..., 3] * np.sin(a) * np.cos(b),  # (4.11)
                        c[..., 2] + c[..., 3] * np.sin(b)], axis=-1)  # (4.12)
        return self._robots(c[..., 0:3], x_b)  # (4.7)-(4.9)

    def cluster_rate(self, r, r_dot, *, near_c=None):
        """Derivative of (4.1)-(4.6); undefined (raises) with the UAV straight above or below the UGV."""
        r, _, d = self._delta(r)
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
        return _rate_from_gradients(grads, self.layout.positions(as_array(r_dot, "r_dot", 6)))

    def robot_rate(self, c, c_dot, *, r=None):
        """Derivative of (4.7)-(4.12) along ``c_dot``; rank 5 with the UAV overhead (``cos beta_c = 0``)."""
        return self.robot_rate_arrays(np.asarray(c, dtype=float), as_array(c_dot, "c_dot", 6))

    def robot_rate_arrays(self, c, cd):
        xp = common_namespace(c, cd)
        rho, a, b = c[..., 3:4], c[..., 4:5], c[..., 5:6]
        ca, sa, cb, sb = xp.cos(a), xp.sin(a), xp.cos(b), xp.sin(b)
        v_b = (cd[..., 0:3] + cd[..., 3:4] * xp.concatenate([ca * cb, sa * cb, sb], -1)
               + cd[..., 4:5] * rho * xp.concatenate([-sa * cb, ca * cb, 0 * cb], -1)
               + cd[..., 5:6] * rho * xp.concatenate([-ca * sb, -sa * sb, cb], -1))
        return self._robots(cd[..., 0:3], v_b)

    def special_sets(self):
        return (
            sp.SpecialSet("overhead", "alpha_c = atan2(dy, dx) of eq. (4.5) is atan2(0, 0) with the UAV straight "
                          "above or below the UGV", sp.ugv_uav_overhead, jacobian="raises",
                          inverse_jacobian="rank-deficient"),
            sp.SpecialSet("behind", "alpha_c passes its branch cut +-pi with the UAV behind the UGV",
                          sp.ugv_uav_behind),
        )

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
    with :class:`~quatform.errors.UnreachableError`; ``from_chart`` (references) holds
    them to the range itself. :meth:`reachable` says where ``forward`` accepts a state.

    Parameters
    ----------
    range_deg : tuple of float
        Allowed range of ``alpha_f`` and ``beta_f`` (seed 001 §4.1.2: 0 to 45 deg).
    tolerance_deg : float
        How far outside the range measured states are still accepted, deg (1).
    """

    name = "restricted"
    key = "ugv-uav-restricted"
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

    def _formulas(self, r):
        """Eqs. (4.13)-(4.18) without checks, and ``z_b - z_p``: ``(c (..., 6), dz (...))`` (any namespace)."""
        xp = namespace(r)
        p = self.layout.positions(r) if xp is np else r.reshape(r.shape[:-1] + (2, 3))
        d = p[..., 1, :] - p[..., 0, :]
        rho = xp.linalg.norm(d, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            alpha = xp.arcsin(xp.clip(d[..., 0] / rho, -1, 1))  # (4.17)
            beta = xp.arcsin(xp.clip(d[..., 1] / rho, -1, 1))  # (4.18)
        # (4.13)-(4.15), (4.16)
        return xp.concatenate([p[..., 0, :], xp.stack([rho, alpha, beta], axis=-1)], axis=-1), d[..., 2]

    def forward_arrays(self, r, near_c=None):
        """Eqs. (4.13)-(4.18) (``near_c`` is not needed: no angle is wound); where
        :meth:`reachable` is False :meth:`forward` refuses the state."""
        return self._formulas(r)[0]

    def reachable(self, r):
        """Where ``r`` is inside the description: the UAV at or above the platform and both
        angles within ``tolerance_deg`` of the range; a bool array (...). Raises nothing (any namespace)."""
        c, dz = self._formulas(as_floats(r))
        out = dz < 0
        for _, bad in self._angles_out(c, self.tolerance):
            out |= bad
        return ~out

    def sample_robot_state(self, rng, batch=()):
        """Random reachable states: ``alpha_f``, ``beta_f`` in [1, 40] deg of the range's low
        edge (scaled to the range), ``rho_f`` in [0.5, 2.5] m, the UGV within 2 m."""
        batch = (int(batch),) if isinstance(batch, (int, np.integer)) else tuple(batch)
        lo, hi = self.range
        a, b = (lo + (hi - lo) * rng.uniform(1 / 45, 40 / 45, batch) for _ in range(2))
        x_p = rng.uniform(-2.0, 2.0, batch + (3,))
        rho = rng.uniform(0.5, 2.5, batch)
        sa, sb = np.sin(a), np.sin(b)
        w = np.sqrt(np.maximum(0.0, 1.0 - sa * sa - sb * sb))
        return self._robots(x_p, x_p + rho[..., None] * np.stack([sa, sb, w], axis=-1))

    def special_sets(self):
        return (
            sp.SpecialSet("overhead", "alpha_f = beta_f = 0, the lower edge of the operating range (asin regular)",
                          sp.ugv_uav_restricted_overhead),
            sp.SpecialSet("corner", "alpha_f = beta_f = 45 deg: the UAV at platform level, (4.24)'s root 0 and its "
                          "derivative infinite (the inverse Jacobian clips it at W_MIN); the root of a rounding "
                          "error there costs half the digits of z_b", sp.ugv_uav_restricted_corner,
                          round_trip_tol=1e-7),
        )

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

    def invertible(self, c):
        """Where :meth:`inverse` accepts the cluster state ``c`` (``(..., 6)``): finite within
        ``MAX_MAGNITUDE``, ``rho_f > 0``, eq. (4.24) with a real root and the angles within
        ``tolerance_deg`` of the range; a bool array (...). Raises nothing (NumPy)."""
        with np.errstate(invalid="ignore", over="ignore"):
            w2 = 1 - np.sin(c[..., 4]) ** 2 - np.sin(c[..., 5]) ** 2
            bad = ~(np.max(np.abs(c), axis=-1) <= MAX_MAGNITUDE) | ~(c[..., 3] > 0) | (w2 < -1e-12)
            for _, out in self._angles_out(c, self.tolerance):
                bad = bad | out
        return ~bad

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
        """The one check of a robot state that :meth:`forward`, :meth:`cluster_rate` and so
        :meth:`jacobian`, :meth:`inverse_jacobian` and :meth:`singularity_measure` share:
        refuse the UAV below the platform and angles more than ``tolerance_deg`` outside the
        range (UnreachableError, where :meth:`reachable` is False). Returns ``(r, delta, c)``."""
        r, _, d = self._delta(r, name)
        c, dz = self._formulas(r)  # (4.13)-(4.18)
        self._refuse_below(dz, name, "use the spherical or quaternion description")
        self.check_reachable(c, name, self.tolerance)
        return r, d, c

    def _expressible_cluster(self, c, name="cluster state"):
        """The check of a cluster state that :meth:`inverse` and :meth:`robot_rate`
        share: ``rho_f > 0`` and the angles within the range and its tolerance."""
        c = self.check_cluster_state(c, "c")
        if np.any(c[..., 3] <= 0):
            raise DegenerateInputError(f"rho_f must be positive, got {float(np.min(c[..., 3]))!r}")
        self.check_reachable(c, name, self.tolerance)
        return c

    def forward(self, r, *, near_c=None):
        return self._expressible(r)[2]

    def inverse(self, c, *, near_r=None):
        return self.inverse_arrays(self._expressible_cluster(c))

    def inverse_arrays(self, c):
        """Eqs. (4.19)-(4.24) of a checked cluster state (any namespace), without the checks."""
        xp = namespace(c)
        sa, sb = xp.sin(c[..., 4]), xp.sin(c[..., 5])
        x_b = xp.stack([c[..., 0] + c[..., 3] * sa,  # (4.22)
                        c[..., 1] + c[..., 3] * sb,  # (4.23)
                        c[..., 2] + c[..., 3] * xp.sqrt(xp.maximum(0.0, 1 - sa * sa - sb * sb))], axis=-1)  # (4.24)
        return self._robots(c[..., 0:3], x_b)  # (4.19)-(4.21)

    def cluster_rate(self, r, r_dot, *, near_c=None):
        """Derivative of (4.13)-(4.18): ``rho' = u . delta'``, ``alpha_f' = (e_x - u_x u) . delta' /
        (rho cos alpha_f)``, ``beta_f'`` alike; singular where ``sin^2 alpha_f + sin^2 beta_f = 1``
        (UAV at platform level). Refuses what :meth:`forward` refuses (UnreachableError: the UAV
        below the platform, angles outside the range): there the description, so its rate,
        does not exist."""
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
        grads = [u, dd[..., 0, :] / (rho * np.sqrt(cos_a2))[..., None], dd[..., 1, :] / (rho * np.sqrt(cos_b2))[..., None]]
        return _rate_from_gradients(grads, self.layout.positions(as_array(r_dot, "r_dot", 6)))

    def singularity_measure(self, r, *, near_c=None):
        """As :meth:`Formation.singularity_measure`; refuses what :meth:`forward` refuses, naming
        the state as given (not the normalised one the measure is taken on)."""
        self._expressible(r)
        return super().singularity_measure(r, near_c=near_c)

    def robot_rate(self, c, c_dot, *, r=None):
        """Derivative of eqs. (4.19)-(4.24) at ``c`` along ``c_dot``; refuses what :meth:`inverse`
        refuses, and ``r`` (if given) where :meth:`forward` refuses it."""
        c = self._expressible_cluster(c)
        if r is not None:
            self._expressible(r)
        return self.robot_rate_arrays(c, as_array(c_dot, "c_dot", 6))

    def robot_rate_arrays(self, c, cd):
        xp = common_namespace(c, cd)
        rho, a, b = c[..., 3:4], c[..., 4:5], c[..., 5:6]
        sa, ca, sb, cb = xp.sin(a), xp.cos(a), xp.sin(b), xp.cos(b)
        # (4.24)'s root: its derivative is infinite at platform level; clipped at W_MIN
        w = xp.sqrt(xp.maximum(W_MIN ** 2, 1 - sa * sa - sb * sb))
        v_b = (cd[..., 0:3] + cd[..., 3:4] * xp.concatenate([sa, sb, w], -1)
               + cd[..., 4:5] * rho * xp.concatenate([ca, 0 * ca, -sa * ca / w], -1)
               + cd[..., 5:6] * rho * xp.concatenate([0 * cb, cb, -sb * cb / w], -1))
        return self._robots(cd[..., 0:3], v_b)

    def from_chart(self, e, e_dot=None):
        S = UgvUavSpherical()
        r = S.inverse(e)
        c, dz = self._formulas(r)
        self._refuse_below(dz, "reference", "use the quaternion description")
        self.check_reachable(c, "reference")
        if e_dot is None:
            return c
        # the dense matrices (not the rate maps) keep the rounding the reference runs were recorded with
        r_dot = np.einsum("...ij,...j->...i", S.inverse_jacobian_at(e), as_array(e_dot, "e_dot", 6))
        return c, np.einsum("...ij,...j->...i", self.jacobian(r), r_dot)


class UgvUavQuaternion(_UgvUav):
    """Eqs. (4.25)-(4.41): cluster point at the UGV, ``q_c`` on the segment, ``d_c = (d, 0, 0)``."""

    name = "quaternion"
    key = "ugv-uav-quaternion"
    variables = (
        Variable("x_c", "m", "position"), Variable("y_c", "m", "position"), Variable("z_c", "m", "position"),
        *quaternion_variables("q_c"),
        Variable("d_c_x", "m", "length"), Variable("d_c_y", "m", "length"), Variable("d_c_z", "m", "length"),
    )
    sign_free = (slice(3, 7),)

    def check_cluster_state(self, c, name="c"):
        c = super().check_cluster_state(c, name)
        as_unit_quaternion(c[..., 3:7], f"{name}[q_c]")
        return c

    def forward(self, r, *, near_c=None):
        r, _, _ = self._delta(r)
        return self.forward_arrays(r, None if near_c is None else self.check_cluster_state(near_c, "near_c"))

    def forward_arrays(self, r, near_c=None):
        xp = namespace(r)
        p = self.layout.positions(r) if xp is np else r.reshape(r.shape[:-1] + (2, 3))
        x_p, d = p[..., 0, :], p[..., 1, :] - p[..., 0, :]
        D = xp.linalg.norm(d, axis=-1)
        u = d / D[..., None]
        if near_c is None:  # eqs. (4.26), (4.28), (4.29): minimal rotation from i
            qh = np.array([1.0, 0.0, 0.0, 0.0])
        else:
            qh = near_c[..., 3:7]
        qc = g.mul(g.swing(g.x_axis(qh), u, g.z_axis(qh)), qh)
        qc = g.closest_sign(qc, qh)
        # (4.25), q_c, (4.27), d_c = (D, 0, 0)
        return g.concat([x_p, qc, D[..., None], xp.zeros(np.shape(D) + (2,))])

    def inverse(self, c, *, near_r=None):
        c = self.check_cluster_state(c)
        qc = c[..., 3:7] / np.linalg.norm(c[..., 3:7], axis=-1, keepdims=True)
        if np.any(np.linalg.norm(c[..., 7:10], axis=-1) <= 0):
            raise DegenerateInputError("d_c must be nonzero (the robots would coincide)")
        return self._robots(c[..., 0:3], c[..., 0:3] + g.rotate(qc, c[..., 7:10]))  # (4.30)-(4.31)

    def cluster_rate(self, r, r_dot, *, near_c=None):
        """``c_dot = J r_dot`` for the forward map near ``near_c`` (no twist rate): ``x_c' = v_p``,
        ``q_c' = 1/2 (0, u x delta' / D) q_c`` (the minimal rotation of eqs. (4.26)-(4.29)),
        ``d_c' = (u . delta', 0, 0)`` (eq. (4.27))."""
        c = self.forward(r, near_c=near_c)
        v = self.layout.positions(as_array(r_dot, "r_dot", 6))
        q = c[..., 3:7]
        u = g.x_axis(q)
        dv = v[..., 1, :] - v[..., 0, :]
        omega = np.cross(u, dv) / c[..., 7:8]
        q_dot = 0.5 * g.mul(g.concat([np.zeros(omega.shape[:-1] + (1,)), omega]), q)
        d_dot = np.sum(u * dv, axis=-1)[..., None]
        return g.concat([v[..., 0, :], q_dot, d_dot, np.zeros(d_dot.shape[:-1] + (2,))])

    def robot_rate(self, c, c_dot, *, r=None):
        """Eq. (4.39) along ``c_dot``: ``v_p = x_c'``, ``v_b = x_c' + d(q d q*)/dq q' + R(q) d'``,
        with (4.40) ``d(q d q*)/dq q' = 2 [w' (w d + u x d) + (u . d) u' + u (d . u') - d (u . u')
        - w (d x u')]`` (seed 001 eq. (2.47), derived form) and (4.41) ``R(q) d' = (w^2 - |u|^2) d'
        + 2 u (u . d') + 2 w (u x d')`` (eq. (2.45)), for ``q = (w, u)`` as given (not normalised)."""
        return self.robot_rate_arrays(np.asarray(c, dtype=float), as_array(c_dot, "c_dot", 10))

    def robot_rate_arrays(self, c, cd):
        xp = common_namespace(c, cd)
        w, u, d = c[..., 3:4], c[..., 4:7], c[..., 7:10]
        wd, ud, dd = cd[..., 3:4], cd[..., 4:7], cd[..., 7:10]

        def dot(a, b):
            return dot_last(a, b)[..., None]

        rot_q = 2.0 * (wd * (w * d + xp.cross(u, d)) + dot(u, d) * ud + u * dot(d, ud) - d * dot(u, ud)
                       - w * xp.cross(d, ud))
        rot_d = (w * w - dot(u, u)) * dd + 2.0 * u * dot(u, dd) + 2.0 * w * xp.cross(u, dd)
        return self._robots(cd[..., 0:3], cd[..., 0:3] + rot_q + rot_d)

    def special_sets(self):
        return (
            sp.SpecialSet("behind", "the minimal rotation from i (eqs. (4.26)-(4.29)) is 0/0 with the UAV behind "
                          "the UGV; the half turn about z is taken. Its (1 + a.u, a x u) cancels nearby: within "
                          "1e-8 rad of the set the UAV comes back to about 1e-8 relative", sp.ugv_uav_behind,
                          round_trip_tol=1e-7),
            sp.SpecialSet("overhead", "the spherical alpha_c is undefined here; q_c is regular",
                          sp.ugv_uav_overhead),
        )

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
