"""The low-level cascades of N quadrotors evaluated together on ``(N, ...)`` arrays.

Robots layer (physical models; no MuJoCo import). :class:`QuadrotorCascades` is
:class:`~quatform.robots.physics.quadrotor.QuadrotorCascade` (PX4-like velocity mode and
Bebop-like attitude mode, the mixer's desaturation, the rotor drag) for a team: every
quantity is an array with one row per vehicle, so one physics step costs a constant number
of NumPy calls whatever N (about 75: ~150 us on this machine, against ~30 us per vehicle
for the per-vehicle cascade on Python floats, so the arrays pay from about six vehicles
on; :data:`quatform.sim.mujoco_backend.VECTORISED_FROM`). The formulas and their sources
are the per-vehicle class's (PX4 ``PositionControl`` and
``ControlAllocationSequentialDesaturation``; Lee, Leok & McClamroch 2010 for the attitude
error): the velocity loop and the mixer operation for operation, the attitude error and the
rotor drag rewritten in body axes with fewer calls (``docs/derivations.md``, "MuJoCo
teams"); the two agree to rounding (``tests/test_mujoco_team.py``: 1e-12 N on
random states).

:func:`rotation_rows` turns the vehicles' unit quaternions ``(w, x, y, z)`` (MuJoCo's
``qpos`` order) into their rotation matrices, row by row, ``(N, 9)``.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import InvalidInputError, NonFiniteError
from .quadrotor import GRAVITY, IRIS, QuadrotorCascade, QuadrotorParams

__all__ = ["QuadrotorCascades", "rotation_rows"]


def _quat_products_to_rows() -> np.ndarray:
    """``C`` (16, 9) with ``R.ravel() = (q q^T).ravel() @ C`` for a unit quaternion ``q``.

    MuJoCo's ``mju_quat2Mat`` (engine_util_spatial.c): ``R00 = q00 + q11 - q22 - q33``,
    ``R01 = 2 (q12 - q03)``, ... with ``qij = q_i q_j`` (seed 001 eq. (2.45) written without
    using ``|q| = 1``, so the rows are those of the state MuJoCo integrates).
    """
    terms = (((0, 0, 1), (1, 1, 1), (2, 2, -1), (3, 3, -1)), ((1, 2, 2), (0, 3, -2)), ((1, 3, 2), (0, 2, 2)),
             ((1, 2, 2), (0, 3, 2)), ((0, 0, 1), (1, 1, -1), (2, 2, 1), (3, 3, -1)), ((2, 3, 2), (0, 1, -2)),
             ((1, 3, 2), (0, 2, -2)), ((2, 3, 2), (0, 1, 2)), ((0, 0, 1), (1, 1, -1), (2, 2, -1), (3, 3, 1)))
    C = np.zeros((16, 9))
    for k, entry in enumerate(terms):
        for i, j, c in entry:
            C[4 * i + j, k] = c
    return C


_Q2R_T = _quat_products_to_rows().T  # (9, 16)


def rotation_rows(q) -> np.ndarray:
    """Rotation matrices of unit quaternions, row by row.

    Parameters
    ----------
    q : ndarray, shape (N, 4)
        ``(w, x, y, z)`` (MuJoCo's free-joint order), unit.

    Returns
    -------
    ndarray, shape (N, 9)
        ``R`` (body to world) of each vehicle, rows first (MuJoCo's ``mju_quat2Mat``
        formula; equal to it within a few ulp: MuJoCo's compiled sums round differently).
        The array is the transpose of a C-contiguous ``(9, N)`` one (each entry's values
        lie together, as :class:`QuadrotorCascades` reads them).
    """
    q = np.asarray(q, dtype=float).T  # (4, N)
    return (_Q2R_T @ (q[:, None] * q[None]).reshape(16, -1)).T


def _rows(x) -> np.ndarray:
    """``x`` (N, k) as ``(k, N)`` with each row contiguous (a view when ``x`` is such a transpose)."""
    return np.ascontiguousarray(np.asarray(x, dtype=float).T)


class QuadrotorCascades:
    """The cascades of ``n`` quadrotors with the same numbers, evaluated together.

    Every method takes and returns ``(n, k)`` arrays (one row per vehicle); inside, each
    quantity is held entry by entry (``(k, n)``, rows contiguous: a NumPy call on a strided
    column costs about three times one on a contiguous row). Pass transposes of
    C-contiguous ``(k, n)`` arrays (:func:`rotation_rows` returns one) and nothing is copied.

    Parameters
    ----------
    n : int
        Number of vehicles.
    params : QuadrotorParams
    **options
        Keyword arguments of :class:`~quatform.robots.physics.QuadrotorCascade` (its gains
        and limits; validated there).

    Attributes
    ----------
    cascade : QuadrotorCascade
        The per-vehicle cascade whose numbers these are.
    """

    def __init__(self, n: int, params: QuadrotorParams = IRIS, **options):
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise InvalidInputError(f"QuadrotorCascades: n must be a positive number of vehicles, got {n!r}")
        try:
            self.cascade = c = QuadrotorCascade(params, **options)
        except TypeError as exc:
            raise InvalidInputError(f"cascade_options {options!r}: {exc}; see QuadrotorCascade's "
                                    "parameters") from None
        self.n, self.params = n, params
        self._vp = np.repeat(np.asarray(c.vel_p, dtype=float)[:, None], n, axis=1)  # (3, n)
        self._vi = np.repeat(np.asarray(c.vel_i, dtype=float)[:, None], n, axis=1)
        J = np.asarray(params.inertia, dtype=float)
        self._kJc = (J * np.asarray(c.rate_p, dtype=float))[:, None]  # (3, 1)
        self._dJ = np.array([J[2] - J[1], J[0] - J[2], J[1] - J[0]])[:, None]  # w x J w, principal axes
        self._i120, self._i201 = np.array([1, 2, 0]), np.array([2, 0, 1])
        pairs = [(j, i) for j in range(4) for i in range(4) if i != j]  # the mixer's loop order
        self._pj, self._pi = np.array([j for j, _ in pairs]), np.array([i for _, i in pairs])
        M = np.linalg.inv(params.mixer())  # the per-vehicle mixer's inverse, the same numbers
        self._M = M  # f_i = sum_k M[i, k] w_k, w = (T, tau_x, tau_y, tau_z)
        self._m0 = M[:, 0:1].copy()  # (4, 1)
        self._fmax = fmax = params.max_thrust
        self._u = [fmax / r for r in M[:, 0].tolist()]
        self._pu_list = [self._u[j] for j in range(4) for i in range(4) if i != j]
        self._pu = np.array(self._pu_list)[:, None]  # u_j of each pair (12, 1)
        # the largest collective thrust every rotor can share, with headroom (QuadrotorCascade)
        self._thrust_max = c.thrust_headroom * min(fmax / r for r in M[:, 0].tolist())
        self._tan_tilt = math.tan(c.tilt_max)
        self._bebop_fz_max = self._thrust_max * math.cos(c.bebop_tilt_max)
        self.reset()
        self.hold_velocity(np.zeros((n, 3)), np.zeros(n))  # hover

    def reset(self):
        """Clear every velocity integrator."""
        self._integral = np.zeros((3, self.n))

    @property
    def integral(self) -> np.ndarray:
        """The velocity integrators, m/s^2 (world frame), shape (n, 3)."""
        return self._integral.T

    @integral.setter
    def integral(self, value):
        value = np.asarray(value, dtype=float)
        if value.shape != (self.n, 3):
            raise InvalidInputError(f"QuadrotorCascades.integral must have shape ({self.n}, 3), got {value.shape}")
        self._integral = _rows(value)

    @staticmethod
    def _check(v, R, omega, what: str):
        """Raise where the state is not finite (checked where the forces are not: every
        non-finite state entry reaches them, NaN through the limits included)."""
        if not all(np.isfinite(x).all() for x in (v, R, omega)):
            raise NonFiniteError(f"{what}: a vehicle's state is not finite (v = {v.T.tolist()!r}); "
                                 "check the physics step")

    # -- set points (held between control ticks) ---------------------------------------
    def hold_velocity(self, v_cmd, yaw_rate_cmd):
        """Hold world-frame velocity (n, 3) and yaw-rate (n,) set points for
        :meth:`velocity_forces` (a non-finite entry holds zero; the yaw rate is limited to
        ``yaw_rate_max``)."""
        vc = _rows(v_cmd)
        self._vc = np.where(np.isfinite(vc), vc, 0.0)
        self._yaw = self._yaw_set_point(np.asarray(yaw_rate_cmd, dtype=float))

    def _yaw_set_point(self, yaw_rate):
        lim = self.cascade.yaw_rate_max
        return np.where(np.isfinite(yaw_rate), np.minimum(np.maximum(yaw_rate, -lim), lim), 0.0)

    def hold_attitude(self, u):
        """Hold Bebop-like commands ``(u_x, u_y, u_z, u_psi)`` (n, 4) for :meth:`attitude_forces`
        (each limited to [-1, 1], a non-finite one 0; seed 001 eq. (3.6))."""
        c = self.cascade
        u = _rows(u)
        u = np.where(np.isfinite(u), np.minimum(np.maximum(u, -1.0), 1.0), 0.0)
        self._climb = u[2] * c.bebop_climb_max
        self._tilt = np.tan(u[0:2] * c.bebop_tilt_max)  # (tan pitch, tan roll) in the heading frame
        self._yaw = self._yaw_set_point(u[3] * c.bebop_yaw_rate_max)

    # -- outer loops ------------------------------------------------------------------
    def velocity_mode(self, v_cmd, yaw_rate_cmd, v, R, omega, dt: float) -> np.ndarray:
        """Rotor forces (n, 4) for world-frame velocity and yaw-rate set points
        (:meth:`hold_velocity` then :meth:`velocity_forces`).

        Parameters
        ----------
        v_cmd : ndarray, shape (n, 3)
            m/s, world frame; a non-finite entry holds that axis at zero.
        yaw_rate_cmd : ndarray, shape (n,)
            rad/s.
        v : ndarray, shape (n, 3)
            World-frame velocities, m/s.
        R : ndarray, shape (n, 9)
            Body-to-world rotations, rows first (:func:`rotation_rows`).
        omega : ndarray, shape (n, 3)
            Body-frame angular velocities, rad/s.
        dt : float
            The integrators' step, s.
        """
        self.hold_velocity(v_cmd, yaw_rate_cmd)
        return self.velocity_forces(v, R, omega, dt)

    def velocity_forces(self, v, R, omega, dt: float) -> np.ndarray:
        """Rotor forces (n, 4) for the held velocity set points (:meth:`velocity_mode`'s
        arguments but the set points; one call per physics step)."""
        c = self.cascade
        v, R, w = _rows(v), _rows(R), _rows(omega)
        before = self._integral
        lim_i = c.vel_i_limit
        err = self._vc - v
        self._integral = np.minimum(np.maximum(self._integral + self._vi * err * dt, -lim_i), lim_i)
        a = self._vp * err + self._integral
        m, g, t_max = self.params.mass, GRAVITY, self._thrust_max
        F = m * a
        nxy = np.hypot(F[0], F[1])
        # the thrust vector within the rotors' reach (QuadrotorCascade.velocity_mode): the
        # vertical demand first, less a margin kept for the horizontal one, then the
        # horizontal within what is left and the tilt limit
        margin = np.minimum(nxy, c.thrust_xy_margin * t_max)
        fz = np.minimum(m * (g + np.minimum(np.maximum(a[2], -0.7 * g), g)), np.sqrt(t_max * t_max - margin * margin))
        F[2] = fz
        lim = np.minimum(fz * self._tan_tilt, np.sqrt(np.maximum(t_max * t_max - fz * fz, 0.0)))
        over = nxy > lim
        if np.count_nonzero(over):
            F[0:2] = np.where(over, F[0:2] * lim / np.where(over, nxy, 1.0), F[0:2])
        f = self._attitude_chain(F, self._yaw, R, w)
        if not math.isfinite(float(np.add.reduce(f, None))):  # a non-finite state reaches the forces
            self._integral = before  # not poisoned for good
            self._check(v, R, w, "velocity_mode")
        return f.T

    def attitude_mode(self, u, v, R, omega) -> np.ndarray:
        """Rotor forces (n, 4) for Bebop-like commands ``(u_x, u_y, u_z, u_psi)`` (n, 4) in [-1, 1]
        (seed 001 eq. (3.6); :meth:`QuadrotorCascade.attitude_mode`): :meth:`hold_attitude`
        then :meth:`attitude_forces`."""
        self.hold_attitude(u)
        return self.attitude_forces(v, R, omega)

    def attitude_forces(self, v, R, omega) -> np.ndarray:
        """Rotor forces (n, 4) for the held Bebop-like commands (one call per physics step)."""
        c = self.cascade
        v, R, w = _rows(v), _rows(R), _rows(omega)
        m, g = self.params.mass, GRAVITY
        az = c.bebop_climb_p * (self._climb - v[2])
        fz = np.minimum(m * (g + np.minimum(np.maximum(az, -0.7 * g), g)), self._bebop_fz_max)
        tx, ty = self._tilt
        ch, sh = R[0], R[3]
        h = np.hypot(ch, sh)
        h = np.where(h == 0.0, 1.0, h)
        ch, sh = ch / h, sh / h
        f = self._attitude_chain(np.stack([fz * (ch * tx - sh * ty), fz * (sh * tx + ch * ty), fz]), self._yaw, R, w)
        if not math.isfinite(float(np.add.reduce(f, None))):  # a non-finite state reaches the forces
            self._check(v, R, w, "attitude_mode")
        return f.T

    # -- inner loops (entry by entry: (k, n) rows) ------------------------------------
    def _attitude_chain(self, F, yaw_rate, R, w) -> np.ndarray:
        """Thrust vectors ``F`` (3, n) and yaw-rate set points (n,) -> attitude set points (heading kept) -> rates -> torques
        -> forces (:meth:`QuadrotorCascade._attitude_chain`, every vehicle): forces (4, n).

        The attitude error is Lee et al.'s ``e_R = 1/2 vee(R_d^T R - R^T R_d)`` with
        ``R_d = [b1 b2 b3]``, ``b3 = F/|F|``, ``b2 = b3 x x_c / |b3 x x_c|``, ``b1 = b2 x b3``,
        evaluated in body axes (``docs/derivations.md``, "MuJoCo teams"): with
        ``beta = R^T b3`` and ``gamma = R^T b2 = beta x chi / |beta x chi|`` (``chi = R^T x_c``),
        ``e_x = (beta_y - gamma_z) / 2`` and ``e_y = ((gamma x beta)_z - beta_x) / 2``; the
        collective thrust is ``F . R e_z = (R^T F)_z``. Fewer NumPy calls than the per-vehicle
        entries, equal to them to rounding.
        """
        c = self.cascade
        Rm = R.reshape(3, 3, -1)  # Rm[i, j] = R_ij of every vehicle
        Fb = np.einsum("kin,kn->in", Rm, F)  # R^T F: the thrust vector in body axes
        n = np.sqrt(np.add.reduce(Fb * Fb, axis=0))  # |F|
        # the heading: the body x axis in the horizontal plane, (R_00, R_10, 0) (not normalised)
        chi = np.einsum("kin,kn->in", Rm[0:2], Rm[0:2, 0])  # R^T (R_00, R_10, 0)
        if np.count_nonzero(chi[0] > 1e-12) < chi.shape[1]:  # body x vertical: world x (QuadrotorCascade)
            chi = np.where(chi[0] > 1e-12, chi, Rm[0])
        (f0, f1, f2), (c0, c1, c2) = Fb, chi
        gam = np.empty_like(Fb)  # R^T (b3 x x_c), times |F|
        gam[0], gam[1], gam[2] = f1 * c2 - f2 * c1, f2 * c0 - f0 * c2, f0 * c1 - f1 * c0
        gam /= np.sqrt(np.add.reduce(gam * gam, axis=0))  # R^T b2
        beta = Fb / n  # R^T b3
        b0, b1 = beta[0], beta[1]
        kp = c.att_p  # yaw_rate: the held set point, finite and within yaw_rate_max
        # rate set point: attitude P on roll and pitch (e_x, e_y); the yaw rate (world z) in body axes
        w_sp = yaw_rate * Rm[2]
        w_sp[0] -= (0.5 * kp) * (b1 - gam[2])
        w_sp[1] -= (0.5 * kp) * (gam[0] * b1 - gam[1] * b0 - b0)
        wrench = np.empty((4, F.shape[1]))
        wrench[0] = np.minimum(np.maximum(Fb[2], 0.0), self._thrust_max)  # F . (body z)
        # rate loop: J k (w_sp - w) + w x J w (principal axes: (J_z - J_y) w_y w_z, ...)
        wrench[1:] = self._kJc * (w_sp - w) + self._dJ * (w[self._i120] * w[self._i201])
        return self._mix_rows(wrench)

    def mix(self, thrust, tau) -> np.ndarray:
        """Rotor forces (n, 4) for collective thrusts (n,) and body torques (n, 3), within
        ``[0, f_max]`` (:meth:`QuadrotorCascade.mix`: roll and pitch first, then the collective
        thrust, then as much yaw as fits), every vehicle at once."""
        return self._mix_rows(np.concatenate([np.asarray(thrust, dtype=float)[None], _rows(tau)])).T

    def _mix_rows(self, wrench) -> np.ndarray:
        """:meth:`mix` on the wrench ``(T, tau_x, tau_y, tau_z)`` entry by entry (4, n): forces (4, n)."""
        M, fmax = self._M, self._fmax
        t0 = np.minimum(np.maximum(wrench[0], 0.0), self._thrust_max)
        wrench[0] = t0
        f = M @ wrench  # f_i = M_i0 T + M_i1 tau_x + M_i2 tau_y + M_i3 tau_z
        sat = (f < 0.0) | (f > fmax)
        if not np.count_nonzero(sat):
            return f
        # QuadrotorCascade.mix's desaturation for every vehicle (the unsaturated keep f)
        t1, t2, t3 = wrench[1], wrench[2], wrench[3]
        m0, u = self._m0, self._u
        rp = M[:, 1:2] * t1 + M[:, 2:3] * t2  # (4, n)
        a = rp / m0
        # the per-vehicle loop over rotor pairs (j, i), in its order and with its test (a
        # pair whose a_j - a_i is nowhere positive never passes it: u_j k > 0)
        d = a[self._pj] - a[self._pi]  # (12, n)
        with np.errstate(divide="ignore"):
            cand = self._pu / d
        k = np.ones_like(t0)
        for p in np.flatnonzero(np.count_nonzero(d > 0.0, axis=1)).tolist():
            hit = d[p] > self._pu_list[p] * k
            k = np.where(hit, cand[p], k)
        ka = k * a
        lo = (-t0 - ka).max(axis=0)
        hi = ((np.asarray(u)[:, None] - t0) - ka).min(axis=0)
        dT = np.minimum(np.maximum(0.0, lo), hi)  # the least change of the collective thrust
        f2 = m0 * (t0 + dT) + k * rp
        y = M[:, 3:4] * t3
        with np.errstate(divide="ignore", invalid="ignore"):
            up = np.where(y > 0.0, (fmax - f2) / np.where(y > 0.0, y, 1.0), np.inf)
            down = np.where(y < 0.0, f2 / np.where(y < 0.0, -y, 1.0), np.inf)
        s = np.maximum(np.minimum(1.0, np.minimum(up.min(axis=0), down.min(axis=0))), 0.0)
        out = np.minimum(np.maximum(f2 + s * y, 0.0), fmax)
        return np.where(sat.any(axis=0), out, f)

    def rotor_drag(self, forces, v, R) -> np.ndarray:
        """World-frame in-plane rotor drag (n, 3), N: ``-c sum_i(omega_i) v_perp`` (RotorS motor
        model; :meth:`QuadrotorCascade.rotor_drag`) for rotor forces (n, 4), world velocities
        (n, 3) and rotations (n, 9)."""
        p = self.params
        F, v, Rm = _rows(forces), _rows(v), _rows(R).reshape(3, 3, -1)
        k = (-p.rotor_drag_coefficient) * np.add.reduce(np.sqrt(np.maximum(F, 0.0) / p.motor_constant), axis=0)
        zb = Rm[:, 2]  # body z in world axes
        return (k * (v - np.add.reduce(v * zb, axis=0) * zb)).T  # v_perp = R P_xy R^T v = v - (v . z_b) z_b
