"""Rigid-formation motion of N robots, fully actuated or airplane-like (seed 004 §3-§4).

Planning layer: imports :mod:`quatform.algebra`, :mod:`quatform.errors` and
:mod:`quatform.planning.se3` (the GA(3) -> SE(3) projection), and SciPy's ODE solver.

The formation is a virtual rigid body with frame {M} at the robots' centroid; robot ``i``
sits at ``d_i(t) = d(t) + R(t) r_i`` (seed 004 eq. (3)), so every pairwise distance is
constant. The kinetic energy splits into the formation's, with the metric of eq. (15),
and each robot's own rotation, with ``G_i = H_i / 2`` (§3.1).

* Fully actuated robots only (§3.1): the formation moves on the projected GA(3) geodesic
  (a straight line ``d(t)`` and the projection of ``R0 + (R1 - R0) t``); each robot's own
  rotation is the projected SO(3) geodesic with its inertia.
* Airplane-like robots (§3.2), whose velocity must lie along their body x axis: the
  formation's twist at each end must lie in the null space of ``C`` (eq. (16)). The
  formation moves on the projected GA(3) minimum-acceleration curve (eqs. (13)-(14))
  whose end twists, free in those null spaces, minimise the ambient energy
  ``E = int Tr(Mdot^T Mdot W) + w |ddot|^2 dt`` *within that two-parameter cubic family*
  (a quadratic, solved exactly). It is not the least energy over all admissible curves:
  with the same ends and end twists, curves of lower energy exist (seed 004 §4 case (b):
  2126.8 J against the cubic's 2409.3 J for a degree-11 polynomial correction; the
  infimum, the straight line's 2105 J, is not attained since the end velocities are
  prescribed; docs/derivations.md, "Planning (seeds 002 and 004)").
  The seed leaves an airplane's attitude between the ends to a path-tracking controller;
  quatform gives it the frame that keeps the body x axis on the velocity with no spin
  about it (the rotation-minimising frame, integrated from ``R_i^0``), plus a smooth roll
  (``3 s^2 - 2 s^3`` of the remaining angle) that lands exactly on ``R_i^1``. So the
  velocity constraint holds along the whole path, not only at the ends.

Public entry points: :func:`rigid_plan_from_spec` (any formation, from a dict) and
:func:`airplanes_plan` (seed 004 §4's five airplanes, cases ``"holonomic"``, ``"a"``,
``"b"``), both returning a :class:`RigidFormationPlan`.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from numbers import Integral, Real

import numpy as np
from scipy.integrate import solve_ivp

from ..algebra import (
    matrix_from_q,
    q_angle_between,
    q_from_axis_angle,
    q_from_matrix,
    qcanonical,
    qmul,
    qnormalize,
    skew,
)
from ..algebra.validate import as_array
from ..errors import (
    DegenerateInputError,
    InvalidInputError,
    ShapeError,
    UnreachableError,
)
from .se3 import ProjectedCurve, w_from_g

__all__ = [
    "ACTUATIONS",
    "AIRPLANE_CASES",
    "RigidFormationPlan",
    "RigidFormationSample",
    "airplane_constraint_matrix",
    "airplanes_plan",
    "airplanes_spec",
    "formation_metric",
    "gamma_matrix",
    "rigid_plan_from_spec",
    "twist_null_space",
]

#: Actuation models of one robot: ``"full"`` (6 DOF, §3.1) or ``"airplane"`` (§3.2).
ACTUATIONS = ("full", "airplane")
#: Cases of seed 004 §4 accepted by :func:`airplanes_plan`.
AIRPLANE_CASES = ("holonomic", "a", "b")

#: Rows selecting a robot's body y and z velocity: seed 004 eq. (16).
_LATERAL = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
#: Keys of a formation spec (see :func:`rigid_plan_from_spec`).
RIGID_SPEC_KEYS = ("masses", "body_points", "inertias", "start", "end", "actuation", "duration", "samples")
_POSE_KEYS = ("position", "orientation", "robot_orientations")


# --------------------------------------------------------------------------- building blocks


def gamma_matrix(r) -> np.ndarray:
    """``Gamma(r) = [-r^, I]``: velocity ``Gamma(r) zeta`` of body point ``r`` (seed 004 eq. (2)).

    Parameters
    ----------
    r : array_like, shape (..., 3)
        Point in the body frame (m).

    Returns
    -------
    ndarray, shape (..., 3, 6)
    """
    r = as_array(r, "r", 3)
    out = np.zeros(r.shape[:-1] + (3, 6))
    out[..., :3] = -skew(r)
    out[..., 3:] = np.eye(3)
    return out


def formation_metric(masses, body_points):
    """The formation's SE(3) metric ``diag(G, w I)`` from point masses (seed 004 eq. (15)).

    ``G = 1/2 sum m_i (-r_i^ r_i^) = 1/2 sum m_i (|r_i|^2 I - r_i r_i^T)``,
    ``w = 1/2 sum m_i``. The matching GL(3) metric (eq. (7)) is ``W = 1/2 sum m_i r_i r_i^T``.

    Parameters
    ----------
    masses : array_like, shape (N,)
        Robot masses (kg), positive.
    body_points : array_like, shape (N, 3)
        Robot reference points ``r_i`` in the formation frame (m), centred:
        ``sum m_i r_i = 0``.

    Returns
    -------
    G : ndarray, shape (3, 3)
    w : float
    """
    m = _masses(masses)
    r = _body_points(body_points, m)
    G = -0.5 * np.einsum("i,ijk->jk", m, skew(r) @ skew(r))
    return G, 0.5 * float(m.sum())


def airplane_constraint_matrix(R, robot_rotations, body_points) -> np.ndarray:
    """``C`` of seed 004 eq. (16): ``C zeta = 0`` iff every robot's velocity is along its x axis.

    Stacks ``[[0, 1, 0], [0, 0, 1]] R_i^T R Gamma(r_i)`` over the given robots: the body-y
    and body-z velocity of robot ``i`` (eq. (4)) for formation twist ``zeta``.

    Parameters
    ----------
    R : array_like, shape (3, 3)
        Formation orientation.
    robot_rotations : array_like, shape (K, 3, 3)
        Orientations of the airplane-like robots.
    body_points : array_like, shape (K, 3)
        Their points in the formation frame.

    Returns
    -------
    ndarray, shape (2K, 6)
    """
    R = as_array(R, "R", (3, 3))
    Ri = as_array(robot_rotations, "robot_rotations", (3, 3))
    r = as_array(body_points, "body_points", 3)
    if Ri.ndim != 3 or r.ndim != 2 or Ri.shape[0] != r.shape[0]:
        raise ShapeError(
            f"robot_rotations (K, 3, 3) and body_points (K, 3) must describe the same K robots, "
            f"got shapes {Ri.shape} and {r.shape}"
        )
    rows = _LATERAL @ np.swapaxes(Ri, -1, -2) @ R @ gamma_matrix(r)  # (K, 2, 6)
    return rows.reshape(-1, 6)


def twist_null_space(C, rtol: float = 1e-9) -> np.ndarray:
    """Orthonormal basis of ``{zeta : C zeta = 0}`` (seed 004 §3.2).

    Parameters
    ----------
    C : array_like, shape (k, 6)
    rtol : float
        Singular values below ``rtol * max(1, sigma_max)`` count as zero.

    Returns
    -------
    ndarray, shape (6, n)
        Columns spanning the null space (``n = 0`` when the formation cannot move).
    """
    C = as_array(C, "C", None)
    if C.ndim != 2 or C.shape[1] != 6:
        raise ShapeError(f"C must have shape (k, 6), got {C.shape}")
    if C.shape[0] == 0:
        return np.eye(6)
    _, s, Vt = np.linalg.svd(C)
    rank = int(np.sum(s > rtol * max(1.0, float(s[0]))))
    return Vt[rank:].T.copy()


# --------------------------------------------------------------------------- validation


def _masses(masses) -> np.ndarray:
    m = as_array(masses, "masses", None)
    if m.ndim != 1 or m.size == 0:
        raise ShapeError(f"masses must be a 1-D array of N >= 1 robot masses, got shape {m.shape}")
    if np.any(m <= 0):
        i = int(np.argmax(m <= 0))
        raise InvalidInputError(f"masses[{i}] = {m[i]!r}; every robot mass must be > 0 kg")
    return m


def _body_points(body_points, m) -> np.ndarray:
    r = as_array(body_points, "body_points", 3)
    if r.shape != (m.size, 3):
        raise ShapeError(f"body_points must have shape ({m.size}, 3) (one point per mass), got {r.shape}")
    c = m @ r / m.sum()
    scale = max(1.0, float(np.abs(r).max()))
    if np.abs(c).max() > 1e-9 * scale:
        raise InvalidInputError(
            f"body_points must be centred on the formation's centre of mass (sum m_i r_i = 0, "
            f"seed 004 §3.1); their weighted centroid is {np.round(c, 12).tolist()} m. "
            "Subtract it from every point (and add R c to the formation's positions)"
        )
    return r


def _metric_pair(G, name):
    """``(G, W)`` with ``W = Tr(G)/2 I - G`` positive semi-definite of rank >= 2."""
    W = w_from_g(G)
    g_eig = np.linalg.eigvalsh(G)
    w_eig = np.linalg.eigvalsh(W)
    scale = max(float(g_eig.max()), 1e-300)
    if g_eig.min() <= 1e-12 * scale:
        raise DegenerateInputError(
            f"{name} must be positive definite; eigenvalues {np.round(g_eig, 12).tolist()}. "
            "A zero principal inertia (a point, a rod, or a formation whose points are "
            "collinear) leaves the rotation about that axis undetermined"
        )
    if w_eig.min() < -1e-9 * scale or w_eig[1] <= 1e-12 * scale:
        raise DegenerateInputError(
            f"{name} is not the inertia of a body that is not collinear: its principal values "
            f"{np.round(2 * g_eig, 12).tolist()} must each be <= the sum of the other two, "
            "strictly for at least two of them (seed 004 eq. (7) needs W = Tr(G)/2 I - G "
            "positive semi-definite of rank >= 2)"
        )
    return G, W


def _rotation(x, name) -> np.ndarray:
    """A rotation matrix from a unit quaternion (4,) or a rotation matrix (3, 3)."""
    a = as_array(x, name, None)
    if a.shape == (4,):
        return matrix_from_q(a)
    if a.shape == (3, 3):
        return matrix_from_q(q_from_matrix(a))  # raises NotARotationError, cleans round-off
    raise ShapeError(f"{name} must be a unit quaternion (w, x, y, z) or a 3 x 3 rotation, got shape {a.shape}")


def _rotations(x, n, name) -> np.ndarray:
    a = as_array(x, name, None)
    if a.shape not in ((n, 4), (n, 3, 3)):
        raise ShapeError(f"{name} must have shape ({n}, 4) or ({n}, 3, 3), got {a.shape}")
    return np.stack([_rotation(a[i], f"{name}[{i}]") for i in range(n)])


def _inertias(x, n) -> np.ndarray:
    a = as_array(x, "inertias", None)
    if a.shape == (n, 3):
        a = np.stack([np.diag(v) for v in a])
    if a.shape != (n, 3, 3):
        raise ShapeError(
            f"inertias must have shape ({n}, 3) (principal moments) or ({n}, 3, 3) (kg m^2 about "
            f"each robot's centre, in its body frame), got {a.shape}"
        )
    return a


def _actuation(x, n) -> np.ndarray:
    items = [x] * n if isinstance(x, str) else list(x) if isinstance(x, (Sequence, np.ndarray)) else None
    if items is None or len(items) != n or any(a not in ACTUATIONS for a in items):
        raise InvalidInputError(
            f"actuation must be one of {ACTUATIONS} or a list of {n} of them, got {x!r}"
        )
    return np.array([a == "airplane" for a in items])


def _pose(p, n, name):
    if not isinstance(p, Mapping):
        raise InvalidInputError(f"spec[{name!r}] must be a dict with keys {_POSE_KEYS}, got {type(p).__name__}")
    unknown = set(p) - set(_POSE_KEYS)
    missing = {"position", "orientation"} - set(p)
    if unknown or missing:
        raise InvalidInputError(
            f"spec[{name!r}]: unknown keys {sorted(unknown)}, missing keys {sorted(missing)}; "
            f"allowed {_POSE_KEYS} (robot_orientations defaults to the formation's orientation)"
        )
    d = as_array(p["position"], f"{name}.position", None)
    if d.shape != (3,):
        raise ShapeError(f"{name}.position must have shape (3,), got {d.shape}")
    R = _rotation(p["orientation"], f"{name}.orientation")
    Ri = (
        _rotations(p["robot_orientations"], n, f"{name}.robot_orientations")
        if "robot_orientations" in p else np.broadcast_to(R, (n, 3, 3)).copy()
    )
    return d, R, Ri


# --------------------------------------------------------------------------- the plan


@dataclass(frozen=True)
class RigidFormationSample:
    """The robots and the virtual body at times ``t`` (shape ``S`` = ``np.shape(t)``).

    Attributes
    ----------
    positions, velocities, accelerations : ndarray, shape (*S, N, 3)
        Robot reference points (m, m/s, m/s^2), world frame.
    orientations : ndarray, shape (*S, N, 4)
        Robot orientations, unit quaternions ``(w, x, y, z)``, continuous in ``t``.
    angular_velocities : ndarray, shape (*S, N, 3)
        Robot angular velocities in the world frame (``qdot = 1/2 omega q``), rad/s.
    centroid, centroid_velocity : ndarray, shape (*S, 3)
        Origin of the formation frame {M} (the robots' centre of mass).
    formation_orientation : ndarray, shape (*S, 4)
        Orientation ``R(t)`` of {M} as a quaternion.
    formation_twist : ndarray, shape (*S, 6)
        Body twist ``(omega, v)`` of the virtual body (seed 004 eq. (1)).
    """

    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    orientations: np.ndarray
    angular_velocities: np.ndarray
    centroid: np.ndarray
    centroid_velocity: np.ndarray
    formation_orientation: np.ndarray
    formation_twist: np.ndarray


def _smoothstep(tau):
    return 3 * tau**2 - 2 * tau**3, 6 * tau * (1 - tau)


@dataclass(frozen=True, eq=False)
class _AirplaneAttitudes:
    """Velocity-aligned attitudes of the airplane-like robots ``index`` (see module doc)."""

    index: np.ndarray  # (K,) robot indices
    solution: object  # scipy OdeSolution of the rotation-minimising frames, (4K,) per tau
    roll: np.ndarray  # (K, 3) rotation vector (body of the frame) taking F(1) to R_i^1

    def evaluate(self, tau, vel, acc, T):
        K = self.index.size
        qF = qnormalize(np.moveaxis(self.solution(np.ravel(tau)).reshape(K, 4, -1), -1, 0))
        qF = qF.reshape(tau.shape + (K, 4))
        s, s_dot = _smoothstep(tau)
        ang = np.linalg.norm(self.roll, axis=-1)
        q_roll = q_from_axis_angle(self.roll, s[..., None] * ang)
        q = qmul(qF, q_roll)
        v, a = vel[..., self.index, :], acc[..., self.index, :]
        omega_f = np.cross(v, a) / np.einsum("...i,...i->...", v, v)[..., None]
        omega = omega_f + np.einsum("...ij,...j->...i", matrix_from_q(qF), self.roll) * (s_dot / T)[..., None, None]
        return q, omega


@dataclass(frozen=True, eq=False)
class RigidFormationPlan:
    """A planned rigid-formation motion (seed 004 §3); sample it with :meth:`sample`.

    Attributes
    ----------
    times : ndarray, shape (n,)
        Evenly spaced times covering ``[0, duration]`` (s), for plots and metrics.
    masses : ndarray, shape (N,)
    body_points : ndarray, shape (N, 3)
        ``r_i`` in the formation frame (m).
    inertias : ndarray, shape (N, 3, 3)
        ``H_i`` (kg m^2) in each robot's body frame.
    airplane : ndarray of bool, shape (N,)
        Which robots are airplane-like (velocity along body x only).
    formation : ProjectedCurve
        The virtual body's ambient curve and its projection.
    G, w :
        The formation metric of eq. (15).
    end_twists : ndarray, shape (2, 6)
        The formation's body twist ``(omega, v)`` (rad/s, m/s) at ``t = 0`` and
        ``t = duration``.
    solve_time_s : float
        Wall time spent building the plan.
    """

    times: np.ndarray
    masses: np.ndarray
    body_points: np.ndarray
    inertias: np.ndarray
    airplane: np.ndarray
    formation: ProjectedCurve
    G: np.ndarray
    w: float
    end_twists: np.ndarray
    solve_time_s: float
    _start: tuple
    _end: tuple
    _robot_curves: tuple
    _airplanes: _AirplaneAttitudes | None

    @property
    def duration(self) -> float:
        return self.formation.duration

    def sample(self, t) -> RigidFormationSample:
        """Every robot's position, velocity, acceleration, orientation and angular velocity.

        Parameters
        ----------
        t : float or array_like, shape S
            Times in ``[0, duration]`` (s).
        """
        t = as_array(t, "t", None)
        T = self.duration
        R, om, d, dd, pos, vel, acc = _robot_kinematics(self.formation, self.body_points, t)
        N = self.body_points.shape[0]
        quat = np.empty(t.shape + (N, 4))
        omega = np.empty(t.shape + (N, 3))
        for i, curve in enumerate(self._robot_curves):
            if curve is None:
                continue
            Ri, omi, *_ = curve.evaluate(t)
            quat[..., i, :] = _continuous_q(self._start[2][i], Ri)
            omega[..., i, :] = np.einsum("...ij,...j->...i", Ri, omi)
        if self._airplanes is not None:
            tau = np.clip(t / T, 0.0, 1.0)
            qa, oma = self._airplanes.evaluate(tau, vel, acc, T)
            quat[..., self._airplanes.index, :] = qa
            omega[..., self._airplanes.index, :] = oma
        v_body = np.einsum("...ji,...j->...i", R, dd)
        return RigidFormationSample(
            positions=pos, velocities=vel, accelerations=acc, orientations=quat,
            angular_velocities=omega, centroid=d, centroid_velocity=dd,
            formation_orientation=_continuous_q(self._start[1], R),
            formation_twist=np.concatenate([om, v_body], axis=-1),
        )

    def metrics(self) -> dict:
        """Checks and costs of the plan.

        Returns
        -------
        dict
            ``max_distance_change_m``: largest change of any pairwise robot distance over
            ``times``; ``max_nonholonomic_violation``: largest body-y/z speed (m/s) of an
            airplane-like robot at ``t = 0`` and ``t = duration`` (0.0 when there is none);
            ``max_path_nonholonomic_violation``: the same over ``times``;
            ``min_forward_speed_mps``: smallest body-x speed of an airplane (nan if none);
            ``end_position_error_m``, ``end_orientation_error_rad``: largest deviation of the
            robots from the requested end poses; ``energy``: ambient energy
            ``int Tr(Mdot^T Mdot W) + w |ddot|^2 dt`` of the formation's GA(3) curve, the
            quantity §3.2 minimises over the cubic (minimum-acceleration) family only, not
            over all curves with the same ends and end twists (J); ``energy_se3``: ``int zeta^T G~ zeta dt`` of the
            projected motion (J); ``energy_robot_rotations``: ``sum int omega_i^T G_i
            omega_i dt`` (J); ``solve_time_s``.
        """
        s = self.sample(self.times)
        diff = s.positions[:, :, None, :] - s.positions[:, None, :, :]
        r = self.body_points
        dist0 = np.linalg.norm(r[:, None, :] - r[None, :, :], axis=-1)
        dchange = float(np.abs(np.linalg.norm(diff, axis=-1) - dist0).max())
        ends = self.sample(np.array([0.0, self.duration]))
        out = {"max_distance_change_m": dchange}
        if self.airplane.any():
            lat_end, fwd_end = _body_speeds(ends, self.airplane)
            lat, fwd = _body_speeds(s, self.airplane)
            out["max_nonholonomic_violation"] = float(lat_end.max())
            out["max_path_nonholonomic_violation"] = float(lat.max())
            out["min_forward_speed_mps"] = float(min(fwd.min(), fwd_end.min()))
        else:
            out["max_nonholonomic_violation"] = 0.0
            out["max_path_nonholonomic_violation"] = 0.0
            out["min_forward_speed_mps"] = float("nan")
        perr, aerr = 0.0, 0.0
        for k, (d, R, Ri) in enumerate((self._start, self._end)):
            want = d + r @ R.T
            perr = max(perr, float(np.abs(ends.positions[k] - want).max()))
            ang = q_angle_between(ends.orientations[k], np.stack([q_from_matrix(x) for x in Ri]))
            aerr = max(aerr, float(ang.max()))
        out["end_position_error_m"] = perr
        out["end_orientation_error_rad"] = aerr
        out["energy"] = self.formation.energy()
        x, wts = np.polynomial.legendre.leggauss(64)
        tq = 0.5 * (x + 1.0) * self.duration
        sq = self.sample(tq)
        z = sq.formation_twist
        ke = np.einsum("...i,ij,...j->...", z[..., :3], self.G, z[..., :3]) + self.w * np.einsum(
            "...i,...i->...", z[..., 3:], z[..., 3:])
        out["energy_se3"] = float(0.5 * self.duration * wts @ ke)
        # Robot i's body angular velocity R_i^T omega_i with G_i = H_i / 2 (seed 004 §3.1).
        Rq = matrix_from_q(sq.orientations)
        wb = np.einsum("...ji,...j->...i", Rq, sq.angular_velocities)
        kr = 0.5 * np.einsum("...ni,nij,...nj->...", wb, self.inertias, wb)
        out["energy_robot_rotations"] = float(0.5 * self.duration * wts @ kr)
        out["solve_time_s"] = self.solve_time_s
        return out


def _robot_kinematics(formation: ProjectedCurve, r, t):
    """Formation ``R, omega, d, ddot`` and robot positions, velocities, accelerations at ``t``."""
    R, om, omd, d, dd, ddd = formation.evaluate(t)
    # seed 004 eq. (3): d_i = d + R r_i, and its derivatives with Rdot = R omega^.
    wr = np.cross(om[..., None, :], r)
    pos = d[..., None, :] + np.einsum("...ij,nj->...ni", R, r)
    vel = dd[..., None, :] + np.einsum("...ij,...nj->...ni", R, wr)
    acc_body = np.cross(omd[..., None, :], r) + np.cross(om[..., None, :], wr)
    acc = ddd[..., None, :] + np.einsum("...ij,...nj->...ni", R, acc_body)
    return R, om, d, dd, pos, vel, acc


def _body_speeds(s: RigidFormationSample, mask):
    """Lateral (body y, z) and forward (body x) speeds of the robots in ``mask``."""
    R = matrix_from_q(s.orientations[..., mask, :])
    vb = np.einsum("...ji,...j->...i", R, s.velocities[..., mask, :])
    return np.linalg.norm(vb[..., 1:], axis=-1), vb[..., 0]


def _continuous_q(R0, R):
    """``q(R0) q(R0^T R)`` with both factors canonical: continuous while ``R`` stays less
    than a half turn from ``R0``, and equal to ``q_from_matrix(R0)`` at ``R = R0``."""
    q0 = q_from_matrix(R0)
    return qmul(q0, qcanonical(q_from_matrix(np.swapaxes(R0, -1, -2) @ R)))


# --------------------------------------------------------------------------- energy minimisation


def _hermite_gram():
    """``Gamma_kl = int_0^1 h_k'(tau) h_l'(tau) dtau`` for the Hermite basis (p0, v0, p1, v1)."""
    from .se3 import HERMITE_BASIS

    x, wts = np.polynomial.legendre.leggauss(3)
    tau = 0.5 * (x + 1.0)
    dp = np.stack([np.zeros_like(tau), np.ones_like(tau), 2 * tau, 3 * tau**2], axis=-1)
    h = dp @ HERMITE_BASIS  # (nodes, 4)
    return 0.5 * np.einsum("q,qk,ql->kl", wts, h, h)


def _ga_vector_map(R):
    """``L (12 x 6)``: body twist ``zeta -> (vec(R omega^), R v)`` (row-major vec), seed 004 §3.2."""
    L = np.zeros((12, 6))
    for k in range(3):
        L[:9, k] = (R @ skew(np.eye(3)[k])).ravel()
    L[9:, 3:] = R
    return L


def _optimal_end_twists(W, w, start, end, N0, N1):
    """End twists (tau units) ``zeta0 = N0 a``, ``zeta1 = N1 b`` minimising the ambient energy
    of the cubic Hermite curve (the minimum within that family, not over all curves).

    ``E(a, b) = sum_kl Gamma_kl y_k^T K y_l`` over the Hermite end data
    ``y = (p0, v0, p1, v1)`` in GA(3) written as 12-vectors, ``K = diag(I3 (x) W, w I3)``:
    a positive definite quadratic in ``(a, b)``; its stationary point is solved exactly.
    """
    Gm = _hermite_gram()
    K = np.zeros((12, 12))
    K[:9, :9] = np.kron(np.eye(3), W)
    K[9:, 9:] = w * np.eye(3)
    p0 = np.concatenate([start[1].ravel(), start[0]])
    p1 = np.concatenate([end[1].ravel(), end[0]])
    A = _ga_vector_map(start[1]) @ N0  # (12, n0)
    B = _ga_vector_map(end[1]) @ N1  # (12, n1)
    free = [A, B]
    fixed = [p0, p1]
    fi, vi = (0, 2), (1, 3)
    H = np.block([[Gm[vi[i], vi[j]] * free[i].T @ K @ free[j] for j in range(2)] for i in range(2)])
    g = np.concatenate([sum(Gm[vi[i], fi[k]] * free[i].T @ K @ fixed[k] for k in range(2)) for i in range(2)])
    x = np.linalg.solve(H, -g)
    n0 = N0.shape[1]
    return N0 @ x[:n0], N1 @ x[n0:]


# --------------------------------------------------------------------------- construction


def _plan(masses, body_points, inertias, airplane, start, end, duration, samples) -> RigidFormationPlan:
    t_start = time.perf_counter()
    T = float(duration)
    G, w = formation_metric(masses, body_points)
    G, W = _metric_pair(G, "the formation metric G of eq. (15) (from masses and body_points)")
    robot_W = [_metric_pair(0.5 * H, f"inertias[{i}] / 2")[1] for i, H in enumerate(inertias)]
    r = body_points
    if airplane.any():
        N0 = twist_null_space(airplane_constraint_matrix(start[1], start[2][airplane], r[airplane]))
        N1 = twist_null_space(airplane_constraint_matrix(end[1], end[2][airplane], r[airplane]))
        for Nk, when in ((N0, "start"), (N1, "end")):
            if Nk.shape[1] == 0:
                raise UnreachableError(
                    f"at the {when} no formation twist keeps every airplane's velocity on its "
                    "body x axis (rank C = 6, seed 004 eq. (16)): the formation cannot move "
                    f"there. Change the airplanes' {when} headings"
                )
        z0, z1 = _optimal_end_twists(W, w, start, end, N0, N1)
        z0, z1 = z0 / T, z1 / T
        formation = ProjectedCurve.min_acceleration(
            start[1], start[0], start[1] @ skew(z0[:3]), start[1] @ z0[3:],
            end[1], end[0], end[1] @ skew(z1[:3]), end[1] @ z1[3:], W, w, T,
        )
    else:
        formation = ProjectedCurve.geodesic(start[1], start[0], end[1], end[0], W, w, T)
    times = np.linspace(0.0, T, int(samples))
    R, om, _, _, dd, _ = formation.evaluate(np.array([0.0, T]))  # fails early if degenerate
    end_twists = np.concatenate([om, np.einsum("kji,kj->ki", R, dd)], axis=-1)
    curves = tuple(
        None if airplane[i] else ProjectedCurve.geodesic(start[2][i], np.zeros(3), end[2][i], np.zeros(3),
                                                         robot_W[i], 1.0, T)
        for i in range(len(masses))
    )
    plan = RigidFormationPlan(
        times=times, masses=masses, body_points=r, inertias=inertias, airplane=airplane,
        formation=formation, G=G, w=w, end_twists=end_twists, solve_time_s=0.0,
        _start=start, _end=end, _robot_curves=curves, _airplanes=None,
    )
    for c in curves:  # every robot rotation must project uniquely along the way
        if c is not None:
            c.evaluate(times)
    if airplane.any():
        plan = _with_airplane_attitudes(plan, np.flatnonzero(airplane), start, end)
    return replace(plan, solve_time_s=time.perf_counter() - t_start)


def _barycentric(x, nodes, weights, values):
    """Barycentric interpolation at scalar ``x`` of ``values`` (n, m) given at ``nodes``."""
    diff = x - nodes
    hit = np.flatnonzero(diff == 0.0)
    if hit.size:
        return values[hit[0]]
    c = weights / diff
    return c @ values / c.sum()


def _frame_rate_interpolant(formation: ProjectedCurve, r, tol: float = 1e-12):
    """Polynomial interpolant of ``T (v x a) / |v|^2`` on ``tau in [0, 1]`` for points ``r``.

    The rate of the rotation-minimising frame of each point's velocity, per unit ``tau``,
    interpolated at Chebyshev-Lobatto nodes (barycentric form): one batched evaluation of
    the formation instead of one per ODE step. The number of nodes doubles (33 to 513)
    until the interpolant matches the exact rate between the nodes to ``tol`` relative;
    the rate is analytic, so this converges geometrically (129 nodes for seed 004 §4).
    """
    T = formation.duration

    def rate(tau):
        *_, v, a = _robot_kinematics(formation, r, tau * T)
        return T * np.cross(v, a) / np.einsum("...i,...i->...", v, v)[..., None]

    for n in (33, 65, 129, 257, 513):
        j = np.arange(n)
        nodes = 0.5 * (1.0 - np.cos(np.pi * j / (n - 1)))
        weights = (-1.0) ** j
        weights[[0, -1]] *= 0.5
        vals = rate(nodes)
        flat = vals.reshape(n, -1)
        mid = 0.5 * (1.0 - np.cos(np.pi * (j[:-1] + 0.5) / (n - 1)))
        approx = np.stack([_barycentric(x, nodes, weights, flat) for x in mid])
        err = np.abs(approx - rate(mid).reshape(n - 1, -1)).max()
        if err <= tol * max(1.0, float(np.abs(vals).max())):
            break
    shape = vals.shape[1:]
    return lambda tau: _barycentric(tau, nodes, weights, flat).reshape(shape)


def _with_airplane_attitudes(plan: RigidFormationPlan, index, start, end) -> RigidFormationPlan:
    """Integrate the rotation-minimising frames of the airplanes' velocities (module doc)."""
    T = plan.duration
    K = index.size
    vel = _robot_kinematics(plan.formation, plan.body_points[index], plan.times)[5]
    speed = np.linalg.norm(vel, axis=-1)
    scale = max(1.0, float(np.abs(plan.body_points).max()) / T, float(speed.max()))
    x0 = np.einsum("kji,kj->ki", start[2][index], vel[0])[:, 0]
    x1 = np.einsum("kji,kj->ki", end[2][index], vel[-1])[:, 0]
    for k in range(K):
        i = int(index[k])
        if speed[:, k].min() <= 1e-9 * scale:
            j = int(np.argmin(speed[:, k]))
            raise UnreachableError(
                f"airplane robot {i} stops at t = {plan.times[j]:.6g} s (speed {speed[j, k]:.3g} m/s): "
                "an airplane cannot hover, and its heading is undefined there. Change the end "
                "poses or the duration"
            )
        for x, when in ((x0[k], "start"), (x1[k], "end")):
            if x <= 0:
                raise UnreachableError(
                    f"the end twist minimising the cubic's energy makes airplane robot {i} fly backwards at "
                    f"the {when} (body x speed {x:.6g} m/s): reverse its {when} heading"
                )

    omega_tau = _frame_rate_interpolant(plan.formation, plan.body_points[index])

    def rhs(tau, y):
        om = omega_tau(tau)  # (K, 3): d/dtau of the frames, world axes
        q = y.reshape(K, 4)
        # qdot = 1/2 (0, omega) q (world-frame rate, docs/conventions.md)
        dw = -np.einsum("ki,ki->k", om, q[:, 1:])
        dv = q[:, :1] * om + np.cross(om, q[:, 1:])
        return 0.5 * np.concatenate([dw[:, None], dv], axis=-1).ravel()

    q0 = np.stack([q_from_matrix(R) for R in start[2][index]])
    sol = solve_ivp(rhs, (0.0, 1.0), q0.ravel(), method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    if not sol.success:
        raise UnreachableError(f"the airplanes' attitude integration failed: {sol.message}")
    qF1 = qnormalize(sol.y[:, -1].reshape(K, 4))
    resid = np.swapaxes(matrix_from_q(qF1), -1, -2) @ end[2][index]
    qr = q_from_matrix(resid)  # canonical: the short way
    ang = 2.0 * np.arctan2(np.linalg.norm(qr[:, 1:], axis=-1), qr[:, 0])
    sin_half = np.linalg.norm(qr[:, 1:], axis=-1)
    roll = np.where(sin_half[:, None] > 0, qr[:, 1:] / np.where(sin_half > 0, sin_half, 1.0)[:, None], 0.0)
    roll = roll * ang[:, None]
    att = _AirplaneAttitudes(index=index, solution=sol.sol, roll=roll)
    return replace(plan, _airplanes=att)


def rigid_plan_from_spec(spec: Mapping) -> RigidFormationPlan:
    """Plan a rigid-formation motion from a plain dict (seed 004 §3).

    Parameters
    ----------
    spec : dict
        ``masses``: (N,) kg. ``body_points``: (N, 3) ``r_i`` in the formation frame, m,
        with ``sum m_i r_i = 0``. ``inertias``: (N, 3) principal moments or (N, 3, 3), kg m^2,
        each robot's inertia about its reference point in its body frame.
        ``start``, ``end``: dicts with ``position`` (3,) of the formation's centroid,
        ``orientation`` of the formation frame (unit quaternion (w, x, y, z) or 3 x 3
        rotation) and optionally ``robot_orientations`` (N, 4) or (N, 3, 3) (default: the
        formation's). ``actuation``: ``"full"``, ``"airplane"`` or a list of N of them
        (default ``"full"``). ``duration``: s (default 1). ``samples``: length of
        ``plan.times`` (default 201).

    Returns
    -------
    RigidFormationPlan

    Raises
    ------
    InvalidInputError, ShapeError, NonFiniteError, NotARotationError
        For a malformed spec (the message names the key and the fix).
    DegenerateInputError
        Collinear formation points, a non-physical inertia, or end rotations a half turn
        apart (the projected curve is not unique).
    UnreachableError
        Airplane-like robots whose end headings admit no formation twist, or whose
        cubic of least energy (§3.2) would stop or fly backwards.
    """
    if not isinstance(spec, Mapping):
        raise InvalidInputError(f"spec must be a dict, got {type(spec).__name__}")
    unknown = sorted(set(spec) - set(RIGID_SPEC_KEYS))
    missing = sorted({"masses", "body_points", "inertias", "start", "end"} - set(spec))
    if unknown or missing:
        raise InvalidInputError(
            f"formation spec: unknown keys {unknown}, missing keys {missing}; allowed keys {RIGID_SPEC_KEYS}"
        )
    m = _masses(spec["masses"])
    n = m.size
    r = _body_points(spec["body_points"], m)
    H = _inertias(spec["inertias"], n)
    airplane = _actuation(spec.get("actuation", "full"), n)
    start = _pose(spec["start"], n, "start")
    end = _pose(spec["end"], n, "end")
    duration = spec.get("duration", 1.0)
    if isinstance(duration, bool) or not isinstance(duration, Real) or not (np.isfinite(duration) and duration > 0):
        raise InvalidInputError(f"duration must be a finite number of seconds > 0, got {duration!r}")
    samples = spec.get("samples", 201)
    if isinstance(samples, bool) or not isinstance(samples, Integral) or samples < 2:
        raise InvalidInputError(f"samples must be an integer >= 2, got {samples!r}")
    return _plan(m, r, H, airplane, start, end, float(duration), int(samples))


# --------------------------------------------------------------------------- seed 004 §4


def _rot(axis, deg):
    return matrix_from_q(q_from_axis_angle(np.eye(3)[axis], np.deg2rad(deg)))


def airplanes_spec(case: str, m: float = 1.0, a: float = 5.0, h: float = 10.0, X: float = 20.0,
                   Y: float = 20.0, duration: float = 1.0) -> dict:
    """The five-airplane formation of seed 004 §4 (Fig. 3) as a spec for :func:`rigid_plan_from_spec`.

    ``r_1 = (4h/5, 0, 0)``, ``r_2..5 = (-h/5, +-a/2, +-a/2)``; every robot starts at the
    identity, the formation at the origin; it ends at ``d^1 = (X, 0, Y)`` with
    ``R^1 = Rot(y, -90 deg)``. Case ``"a"``: the airplanes end at the identity; case
    ``"b"``: at the seed's ``Rot(z, .) Rot(y, -45)``; ``"holonomic"``: fully actuated,
    ending as in case (b) (the seed does not say; positions do not depend on it).

    The seed gives no airplane inertia; each airplane here is a solid box 1 m long (x),
    1.2 m wide (y) and 0.2 m high (z) of mass ``m``. It only shapes the holonomic robots'
    own rotations.
    """
    if case not in AIRPLANE_CASES:
        raise InvalidInputError(f"case must be one of {AIRPLANE_CASES}, got {case!r}")
    r = np.array([
        [4 * h / 5, 0, 0],
        [-h / 5, a / 2, a / 2],
        [-h / 5, -a / 2, a / 2],
        [-h / 5, -a / 2, -a / 2],
        [-h / 5, a / 2, -a / 2],
    ])
    lx, ly, lz = 1.0, 1.2, 0.2
    box = m / 12.0 * np.array([ly**2 + lz**2, lx**2 + lz**2, lx**2 + ly**2])
    eye5 = np.broadcast_to(np.eye(3), (5, 3, 3))
    if case == "a":
        end_robots = eye5
    else:
        end_robots = np.stack([
            _rot(1, -90),
            _rot(2, -135) @ _rot(1, -45),
            _rot(2, -45) @ _rot(1, -45),
            _rot(2, 45) @ _rot(1, -45),
            _rot(2, 135) @ _rot(1, -45),
        ])
    return {
        "masses": np.full(5, float(m)),
        "body_points": r,
        "inertias": np.tile(box, (5, 1)),
        "start": {"position": np.zeros(3), "orientation": np.eye(3), "robot_orientations": eye5},
        "end": {"position": np.array([X, 0.0, Y]), "orientation": _rot(1, -90), "robot_orientations": end_robots},
        "actuation": "full" if case == "holonomic" else "airplane",
        "duration": duration,
    }


def airplanes_plan(case: str) -> RigidFormationPlan:
    """Seed 004 §4's five airplanes (m = 1, a = 5, h = 10, X = Y = 20), Fig. 4's cases.

    Parameters
    ----------
    case : {"holonomic", "a", "b"}

    Returns
    -------
    RigidFormationPlan
    """
    return rigid_plan_from_spec(airplanes_spec(case))
